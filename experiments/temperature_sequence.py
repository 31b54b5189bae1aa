"""Temperature of a recording's planes over time: the paper's four flames flickering, in colour.

Writes ``<out>/temperature_sequence.{csv,md,json,png}``.

- **Recording**: :func:`lf_flame.simulate.scenes_time.flicker_sequence` (the paper's four flames at
  their depths, each flickering at its own frequency, 5-20 Hz, its centreline swaying) at ``--fps``
  for ``--frames`` frames, seeded by :data:`SEED` (drawn for this script: neither a validation nor a
  scored seed of ``experiments/temperature.py``). Each frame is
  :func:`lf_flame.simulate.scenes_temperature.colour_flicker_frame`: each flame's temperature field
  in that frame's coordinates, its sheath oscillating by ``FLICKER_K`` at the flame's frequency
  (hottest when shortest). One exposure for the recording: frame 0's brightest texel at
  :data:`EXPOSURE_PEAK` of saturation. Each channel traced at ``--rays`` rays per pixel, mosaicked,
  clipped; then shot and 2 e- read noise at each SNR of ``--snr`` (``experiments/temperature.py``'s
  ``add_noise``, measured per frame). Own error: frame 0 traced again with a second seed.
- **Temperature**: the shipped route, ``admm-cfa-matched`` (its knobs and ratio filter by each
  frame's measured noise), and the calibration of ``make temperature``
  (``results/temperature_calibration.json``): each plane's temperature map per frame. The knobs
  were chosen on other scenes; nothing is chosen here.
- **Per frame and plane**: the median of the true temperature over the pixels with >= 10 % of the
  plane's true peak R+G emission (``t_true_k``), the median of the route's temperature over
  those it reports (``t_k``), and per pixel ``|T - T_true|`` (median, p90), as ``make temperature``
  scores a plane.
- **Per plane over time**: the error of ``t_k`` against ``t_true_k`` (its mean, the route's static
  bias, and the rest: p90 and worst over frames); a sinusoid at the flame's true frequency fitted to
  both by least squares (amplitude K, phase); the dominant frequency of ``t_k``'s spectrum
  (:mod:`lf_flame.recordings.flicker`).

Usage: ``python experiments/temperature_sequence.py --out results [--quick]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parent))
import temperature as E  # noqa: E402  (camera, sensor, calibration, noise and scoring of make temperature)

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.measure.metrics import own_error  # noqa: E402
from lf_flame.temperature import pyrometry as P  # noqa: E402
from lf_flame.recordings.flicker import peaks, spectra  # noqa: E402
from lf_flame.refocus.shift_and_sum import raw_to_views  # noqa: E402
from lf_flame.simulate.colour import render_colour  # noqa: E402
from lf_flame.simulate.scenes_temperature import FLAME_PEAK_K, FLICKER_K, colour_flicker_frame  # noqa: E402
from lf_flame.simulate.scenes_time import flicker_sequence  # noqa: E402
from lf_flame.temperature.channels import channel_emission, route_operator  # noqa: E402
from lf_flame.temperature.mosaic import channel_views  # noqa: E402

#: the recording's seed (frequencies, amplitudes, phases, jitter; ray samples and noise from it)
SEED = 2026_11_25
#: frame 0's brightest texel of any channel, a fraction of saturation: headroom for the hotter frames
EXPOSURE_PEAK = 0.6
ROUTE = "admm-cfa-matched"


def frame_rows(cam, sensor, model, cal, seq, i, exposure, ops, chan, rays, snrs):
    """One frame: rendered, each SNR's noise, the route's temperature and the truth -> rows (one per noise
    level and plane); frame 0's rows carry ``own_error``, from a second render with another seed. ``chan``:
    the views' channel map (:func:`channel_views`), the same for every frame."""
    cs = colour_flicker_frame(seq, cam, sensor, i, exposure=exposure)
    clean = render_colour(cam, cs.scene, cs.channel_radiance, sensor, rays, seq.seed + i)
    extra = {}
    if i == 0:
        other = render_colour(cam, cs.scene, cs.channel_radiance, sensor, rays, seq.seed + 10_000)
        extra["own_error"] = own_error(clean, other)
    Tt, vt = E.true_temperature(cs, ops["truth"], cal, model)
    rows = []
    for j, snr in enumerate(snrs):
        raw, _ = E.add_noise(clean, cs.scene.effects, seq.seed + 100_000 * (j + 1) + i, snr)
        info = {}
        a, b = channel_emission(ROUTE, raw_to_views(raw, cam.pixels_per_lenslet), chan, (0, 1), op=ops["route"],
                                info=info)
        T, valid, _ = P.temperature_planes(a, b, cal, model)
        scored = E.score(ROUTE, f"{snr:g}dB", i, a, b, Tt, vt, cal, model, time_s=i / seq.fps,
                         regime=info["regime"], snr_db=E.snr_db(clean, raw))
        for k, row in enumerate(scored):
            sel = vt[k] & valid[k]
            rows.append(dict(row, frame=i, depth_mm=seq.flames[k].depth_offset_mm,
                             sheath_true_k=cs.scene.objects[k]["peak_k"], t_true_k=float(np.median(Tt[k][vt[k]])),
                             t_k=float(np.median(T[k][sel])) if sel.any() else np.nan, **extra))
    return rows


def sinusoid(t, x, hz):
    """Least-squares ``c + A sin(2 pi hz t + phi)`` of ``x`` over times ``t`` (s): (A in x's units, phi in
    degrees); NaN samples left out."""
    ok = np.isfinite(x)
    w = 2 * np.pi * hz * t[ok]
    (_, s, c), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), np.sin(w), np.cos(w)], 1), x[ok], rcond=None)
    return float(np.hypot(s, c)), float(np.degrees(np.arctan2(c, s)))


def over_time(df, seq):
    """Per noise level and plane: the median temperature's error over the frames, its oscillation at the
    flame's frequency against the truth's, and the dominant frequency of its spectrum."""
    out = []
    for (noise, k), g in df.groupby(["noise", "plane"], sort=True):
        g = g.sort_values("frame")
        e = (g.t_k - g.t_true_k).to_numpy()
        hz = seq.flames[k].freq_hz
        a_t, p_t = sinusoid(g.time_s.to_numpy(), g.t_true_k.to_numpy(), hz)
        a_m, p_m = sinusoid(g.time_s.to_numpy(), g.t_k.to_numpy(), hz)
        rest = np.abs(e - np.nanmean(e))
        out.append(dict(noise=noise, plane=k, depth_mm=seq.flames[k].depth_offset_mm, flicker_hz=hz,
                        bias_k=float(np.nanmean(e)), rest_p90_k=float(np.nanpercentile(rest, 90)),
                        rest_worst_k=float(np.nanmax(rest)), frames_without_t=int(np.isnan(e).sum()),
                        amp_true_k=a_t, amp_k=a_m, phase_error_deg=float((p_m - p_t + 180) % 360 - 180),
                        pixel_p90_median_k=float(g.p90_k.median()), pixel_p90_worst_k=float(g.p90_k.max())))
    res = pd.DataFrame(out)
    for noise, g in df.groupby("noise", sort=True):
        pk = peaks(spectra(g, seq.fps, signals=("t_k",)), [f.freq_hz for f in seq.flames])
        for r in pk.itertuples():
            res.loc[(res.noise == noise) & (res.plane == r.plane), "dominant_hz"] = r.dominant_hz
    return res


def figure(df, seq, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, len(seq.flames), figsize=(4.2 * len(seq.flames), 3.6), sharex=True)
    for k, f in enumerate(seq.flames):
        g = df[df.plane == k]
        first = g[g.noise == g.noise.iloc[0]].sort_values("frame")
        ax[k].plot(first.time_s, first.t_true_k, "k-", lw=2, label="truth (median)")
        for noise, h in g.groupby("noise", sort=True):
            h = h.sort_values("frame")
            ax[k].plot(h.time_s, h.t_k, ".-", lw=0.8, ms=3, label=f"{ROUTE}, {noise}")
        ax[k].set_title(f"plane {k}: {f.depth_offset_mm:+g} mm, flicker {f.freq_hz:g} Hz", fontsize=9)
        ax[k].set_xlabel("time (s)")
    ax[0].set_ylabel("median temperature over the flame (K)")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--calibration", type=Path, default=Path("results"),
                    help="folder holding temperature_calibration.json (make temperature)")
    ap.add_argument("--fps", type=float, default=100.0)
    ap.add_argument("--frames", type=int, default=64)
    ap.add_argument("--rays", type=int, default=400)
    ap.add_argument("--snr", type=float, nargs="+", default=[14.0, 20.0], help="SNR levels (dB) of the noise")
    ap.add_argument("--cache", type=Path, default=Path("data/temperature_sequence"),
                    help="frames done (resumes a stopped run with the same settings and commit)")
    ap.add_argument("--quick", action="store_true", help="8 frames, 16 rays, 14 dB only (a smoke test)")
    a = ap.parse_args(argv)
    if a.quick:
        a.frames, a.rays, a.snr = 8, 16, [14.0]
    t0 = time.perf_counter()
    cam, sensor, model, cal = E.setup(a.calibration)
    seq = flicker_sequence(cam, np.random.default_rng(SEED), "paper", fps=a.fps, duration_s=a.frames / a.fps)
    depths = [f.depth_offset_mm for f in seq.flames]
    ops = dict(truth=route_operator(cam, depths, "admm-cfa"), route=route_operator(cam, depths, ROUTE))
    exposure = colour_flicker_frame(seq, cam, sensor, 0, peak=EXPOSURE_PEAK).exposure
    chan = channel_views(cam.sensor_shape, sensor, cam.pixels_per_lenslet)
    # frames done are kept in a cache named by the settings, so that a stopped run resumes
    a.cache.mkdir(parents=True, exist_ok=True)
    cache = a.cache / (f"frames_seed{SEED}_fps{a.fps:g}_n{a.frames}_rays{a.rays}_snr{'-'.join(f'{x:g}' for x in a.snr)}"
                       f"_{provenance().get('git_commit', 'nogit')[:12]}.csv")
    df = pd.read_csv(cache) if cache.exists() else pd.DataFrame()
    done = set(df.frame) if len(df) else set()
    for i in tqdm(range(seq.n_frames), desc="frames", initial=len(done), total=seq.n_frames):
        if i in done:
            continue
        new = frame_rows(cam, sensor, model, cal, seq, i, exposure, ops, chan, a.rays, a.snr)
        df = pd.concat([df, pd.DataFrame(new)], ignore_index=True)
        atomic_write_text(cache, df.to_csv(index=False))
    df = df.sort_values(["frame", "noise", "plane"], ignore_index=True)
    meta = dict(own_error=float(df.own_error.dropna().iloc[0]), resumed_frames=len(done))
    write(a, seq, df, over_time(df, seq), meta, time.perf_counter() - t0)


def write(a, seq, df, res, meta, wall):
    a.out.mkdir(parents=True, exist_ok=True)
    stem = "temperature_sequence_quick" if a.quick else "temperature_sequence"
    cmd = f"python experiments/temperature_sequence.py --out {a.out}" + (" --quick" if a.quick else "")
    df.to_csv(a.out / f"{stem}.csv", index=False)
    figure(df, seq, a.out / f"{stem}.png")
    prov = provenance()
    snr = df.groupby("noise").snr_db.agg(["min", "max"]).round(2)
    lines = [
        "# Temperature of a recording's planes over time", "",
        f"Command: `{cmd}`; wall time {wall:.0f} s; commit {prov.get('git_commit')}.",
        f"Recording: `flicker_sequence` 'paper' (seed {SEED}), {seq.n_frames} frames at {seq.fps:g} frames/s "
        f"({seq.n_frames / seq.fps:g} s); flicker {[f.freq_hz for f in seq.flames]} Hz; sheath "
        f"{FLAME_PEAK_K} K +- {FLICKER_K:g} K at each flame's frequency (`colour_flicker_frame`); exposure "
        f"frame 0's peak at {EXPOSURE_PEAK} of saturation; {a.rays} rays/pixel per channel (own error of frame 0 "
        f"{meta['own_error']:.4f}); frames resumed from the cache: {meta['resumed_frames']}; measured SNR per "
        f"level (min, max over frames): {snr.to_dict('index')} dB.",
        f"Route: `{ROUTE}` as shipped (regime by each frame's noise: {sorted(df.regime.unique())}); calibration "
        f"`{a.calibration / 'temperature_calibration.json'}`.", "",
        "Per plane (0-3: +20, +10, 0, -10 mm): `t_k` = median temperature over the pixels the route reports among "
        "those >= 10 % of the plane's true peak, against `t_true_k`, the truth's median there. `bias_k`: the mean of "
        "`t_k - t_true_k` over the frames (the route's static bias); `rest_p90_k`, `rest_worst_k`: p90 and worst "
        "of what remains (the frame-to-frame tracking error); `amp_*`, `phase_error_deg`: the sinusoid at the "
        "flame's frequency fitted to `t_true_k` and `t_k`; `dominant_hz`: the largest peak of `t_k`'s spectrum "
        f"(bins {seq.fps / seq.n_frames:g} Hz); `pixel_p90_*`: each frame's p90 of |T - T_true| over the pixels, "
        "median and worst over the frames.", "",
        res.to_markdown(index=False, floatfmt=".1f"), "",
        f"Figure: [{stem}.png]({stem}.png); rows: [{stem}.csv]({stem}.csv).", ""]
    atomic_write_text(a.out / f"{stem}.md", "\n".join(lines))
    atomic_write_text(a.out / f"{stem}.json", json.dumps(dict(
        command=cmd, seed=SEED, fps=seq.fps, frames=seq.n_frames, rays=a.rays, snr_db=a.snr, flicker_k=FLICKER_K,
        exposure_peak=EXPOSURE_PEAK, sequence=seq.to_dict(), wall_s=wall, provenance=prov, **meta),
        indent=1, default=str))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
