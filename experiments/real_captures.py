"""Real light fields (``make real-data``): calibrate, decode and refocus napari-lf's three captures.

napari-lf 0.1.7 (BSD-3) ships three real light-field microscopy captures (plenoptic 1.0:
microlens array at the image plane, sensor at its focus), each a light-field frame, a
radiometry (white) frame and a dark frame, with the optics in a README or metadata file.
The Makefile installs the package with ``pip --no-deps --target`` into its own folder;
this script reads its ``napari_lf/examples`` files only (lf_flame never imports napari_lf).

For each capture, measured in this run:

- :func:`lf_flame.calibrate.calibrate` on the white frame minus the dark frame: pitch,
  rotation, offset, fit residual (px) and wall time;
- an independent pitch: the peak of the periodogram of the white image's mean row and
  column profiles (SciPy, Hann window, zero-padded to 2^20 points), and the pitch the
  stated optics imply (lenslet pitch / pixel size, parsed from the capture's files);
- :func:`lf_flame.calibrate.decode` of the light-field frame (dark-subtracted,
  white-normalised) into N × N views, N the pitch rounded down;
- the slope search (:func:`lf_flame.refocus.find_sharpest_slope`, Fourier slice,
  Tenengrad, circular aperture, slopes -2 to 2) on the brightest structure of the
  centre view, and its sharpness curve: the peak over the curve's ends, the full width
  at half maximum (slope units), and whether the peak lies inside the searched range;
- a figure: the white image with fitted (lattice) and measured centres, the centre
  view, the sharpness curve and a focal stack of 6 planes (shift-and-sum).
- optionally (``--plenopticam DIR``), PlenoptiCam 0.9.3's own lenslet-centre detection
  (``CentroidExtractor`` then ``CentroidSorter``) on the same white image: its centres
  matched to ours (nearest within half a pitch) and both run times.

Writes ``<out>/<capture>.png``, ``<out>/summary.csv``, ``<out>/summary.md`` and
``<out>/summary.json`` (with provenance).

Usage: ``python experiments/real_captures.py --data .bench/napari-lf/napari_lf/examples --out results/real
[--plenopticam .bench/plenopticam]``.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import ndimage, signal

from lf_flame import calibrate
from lf_flame.config import atomic_write_text, provenance
from lf_flame.refocus import aperture_mask, find_sharpest_slope, refocus_views

#: file names of each capture in napari_lf/examples (light field, white, dark, optics files)
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
    """PlenoptiCam's centroid modules from a ``pip --target`` folder, or None."""
    if not path or not Path(path).is_dir():
        return None
    sys.path.insert(0, str(path))
    try:
        from plenopticam.lfp_calibrator import CentroidExtractor, CentroidSorter
        from plenopticam.cfg import PlenopticamConfig
        from plenopticam.misc import PlenopticamStatus
    except Exception as e:  # an optional baseline: any import failure means "not there"
        print(f"PlenoptiCam not usable from {path}: {e!r}")
        return None
    return CentroidExtractor, CentroidSorter, PlenopticamConfig, PlenopticamStatus


def plenopticam_centres(mod, white: np.ndarray, pitch_hint: float):
    """PlenoptiCam's lenslet centres (K, 2) (row, column; our pixel coordinates) and seconds."""
    CentroidExtractor, CentroidSorter, PlenopticamConfig, PlenopticamStatus = mod
    cfg = PlenopticamConfig()
    cfg.calibs = {}
    sta = PlenopticamStatus()
    img = np.clip(white / np.percentile(white, 99.5), 0, 1)
    t = time.perf_counter()
    ext = CentroidExtractor(img, cfg, sta, M=int(round(pitch_hint)))
    ext.main()
    srt = CentroidSorter(ext.centroids, cfg, sta)
    srt.main()
    dt = time.perf_counter() - t
    c = np.asarray(srt.mla_centroids if getattr(srt, "mla_centroids", None) is not None else ext.centroids)
    return c[:, :2] + 0.5, dt   # PlenoptiCam: pixel centres at integers


def figure(path, name, white, cal, views, roi, search, slopes, stack):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(16, 8.5), constrained_layout=True)
    gs = fig.add_gridspec(2, len(slopes))
    ax = fig.add_subplot(gs[0, :2])
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
    ax.legend(fontsize=8, loc="upper right")
    n = views.shape[0]
    ax = fig.add_subplot(gs[0, 2:4])
    cv = views[n // 2, n // 2]
    ax.imshow(cv, cmap="gray", vmin=0, vmax=np.percentile(cv, 99.5))
    ax.add_patch(plt.Rectangle((roi[2] - 0.5, roi[0] - 0.5), roi[3] - roi[2], roi[1] - roi[0], fill=False,
                               ec="y", lw=1))
    ax.set_title(f"centre view of {n} x {n}, {views.shape[2]} x {views.shape[3]} lenslets\n"
                 "(box: ROI of the slope search)", fontsize=9)
    ax = fig.add_subplot(gs[0, 4:])
    ax.plot(search.slopes, search.scores / search.scores.max(), ".-", ms=3)
    ax.axvline(search.slope, color="r", lw=0.8)
    ax.set_xlabel("slope (lenslets per view)")
    ax.set_ylabel("Tenengrad / max")
    ax.set_title(f"sharpness of the ROI (Fourier slice, Tenengrad)\npeak at slope {search.slope:+.3f}",
                 fontsize=9)
    vmax = np.percentile(stack, 99.5)
    for k, (s, im) in enumerate(zip(slopes, stack)):
        ax = fig.add_subplot(gs[1, k])
        ax.imshow(im, cmap="gray", vmin=0, vmax=vmax)
        ax.set_title(f"shift-and-sum, slope {s:+.2f}", fontsize=9)
        ax.axis("off")
    fig.suptitle(f"{name}: napari-lf 0.1.7 example capture, calibrated and decoded by lf_flame", fontsize=11)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def run(data: Path, out: Path, plenopticam_dir=None) -> pd.DataFrame:
    out.mkdir(parents=True, exist_ok=True)
    pcam = _load_plenopticam(plenopticam_dir)
    rows = []
    for name, (lf_file, white_file, dark_file, optics_files) in CAPTURES.items():
        raw = calibrate.load_image(data / lf_file)
        white = calibrate.load_image(data / white_file)
        dark = calibrate.load_image(data / dark_file)
        t = time.perf_counter()
        cal = calibrate.calibrate(white, dark, camera_id=name)
        t_cal = time.perf_counter() - t
        p_cols, p_rows = periodogram_pitch(white - dark)
        p_per = 0.5 * (p_cols + p_rows)
        pitch_um, pixel_um, src = stated_optics(data, optics_files)
        p_stated = pitch_um / pixel_um
        t = time.perf_counter()
        views = calibrate.decode(raw, cal, white, dark, camera_id=name)
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
            pc, t_pc = plenopticam_centres(pcam, white - dark, cal.pitch_px)
            ours = cal.lenslets[:, 2:]
            d = np.hypot(pc[:, None, 0] - ours[None, :, 0], pc[:, None, 1] - ours[None, :, 1])
            near = d.min(axis=1)
            matched = near < 0.5 * cal.pitch_px
            row.update(plenopticam_centres=len(pc), plenopticam_matched=int(matched.sum()),
                       plenopticam_vs_ours_rms_px=round(float(np.sqrt(np.mean(near[matched] ** 2))), 3),
                       plenopticam_vs_ours_median_px=round(float(np.median(near[matched])), 3),
                       plenopticam_s=round(t_pc, 2))
        rows.append(row)
        print(json.dumps(row))
    df = pd.DataFrame(rows)
    df.to_csv(out / "summary.csv", index=False)
    atomic_write_text(out / "summary.md", "# Real captures: lenslet-grid calibration and decoding\n\n"
                      "Written by `experiments/real_captures.py` (`make real-data`); every number measured "
                      "in that run.\n\n" + df.to_markdown(index=False) + "\n")
    atomic_write_text(out / "summary.json", json.dumps({"rows": rows, "provenance": provenance()}, indent=1,
                                                      default=str))
    return df


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True, help="napari_lf/examples folder")
    ap.add_argument("--out", required=True)
    ap.add_argument("--plenopticam", help="folder with PlenoptiCam installed (pip install --no-deps --target)")
    a = ap.parse_args(argv)
    data = Path(a.data)
    if not data.is_dir():
        raise SystemExit(f"error: no napari-lf example folder at {data} (make real-data installs it)")
    print(run(data, Path(a.out), a.plenopticam).to_string(index=False))


if __name__ == "__main__":
    main()
