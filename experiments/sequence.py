"""Flame recordings: each plane's flicker frequency, the overlap case, and what
the per-frame work costs serially and on Dask. Writes ``results/sequence.{md,csv}``,
``results/sequence_speed.csv``, ``results/sequence.json`` and the figures.

    python experiments/sequence.py --out results                       # bars and speed (~10 min)
    python experiments/sequence.py --out results --stage reconstruct   # overlap with pd-tv (~30 min)
    python experiments/sequence.py --out results --stage report        # the report from the CSVs

Stages:
- ``bars``: the paper's four flames and the two-flame overlap, 1 s at 500 frames/s,
  noise-free and with shot and read noise (12 bits), shift-and-sum: each plane's dominant
  frequency against its flame's, and how far the other flames' frequencies lie below it.
- ``reconstruct``: the overlap at 100 frames/s for 1 s with each plane's emission
  (``reconstruct-pd-tv``) on 2 local workers, beside shift-and-sum on the same frames.
- ``speed``: frames/s of the per-frame work (read, refocus four planes, diagnostics) on a
  stored recording: serially (Numba's threads) and on 1 and 2 single-thread local Dask
  workers, interleaved, twice each; the split between reading, refocusing, measuring
  and scheduling; what it means for 10,000 frames. Beside them, interleaved in the same
  run, 1 worker reading the HDF5 file with one open per frame (the earlier reading,
  :class:`PerFrameH5`) against one open per chunk.
- ``stream``: each plane's emission by admm frame after frame on one thread (one core):
  every frame solved from scratch against each chunk's frames continuing the previous
  frame's solve (the recordings' route), interleaved frame by frame, both scored against
  the truth; writes ``results/sequence_stream.{csv,md}``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.cli.sequence import NOISE
from lf_flame.config import atomic_write_text, provenance
from lf_flame.simulate.scenes_time import flicker_sequence
from lf_flame.recordings.sources import H5Source, SimulatedSource, open_source, write_frames
from lf_flame.recordings.runner import run
from lf_flame.recordings.job import CHUNK, simulated_job

SEED_PAPER, SEED_OVERLAP = 26001, 26002
#: the overlap of ``lf-flame sequence --simulate overlap --fps 100 --duration 1`` (seed 0)
SEED_RECON = 0


@dataclasses.dataclass(frozen=True)
class PerFrameH5(H5Source):
    """The earlier HDF5 reading: the file opened once for every frame."""

    def frames(self, start: int, stop: int):
        return (self.raw(i) for i in range(int(start), int(stop)))


#: The speed stage's modes: (name, local workers or None for serial, one open per frame).
SPEED_MODES = (("serial (Numba, 2 threads)", None, False), ("Dask, 1 worker", 1, False),
               ("Dask, 2 workers", 2, False), ("Dask, 1 worker, one open per frame", 1, True))


def _peaks(out: Path, **labels) -> pd.DataFrame:
    pk = pd.read_csv(out / "peaks.csv")
    fr = pd.read_csv(out / "frames.csv")
    err = fr.height_err_mm.abs().groupby(fr.plane)
    pk = pk.merge(pd.DataFrame(dict(height_err_mm_mean=err.mean(), height_err_mm_p90=err.quantile(0.9),
                                    height_err_mm_max=err.max(), share_over_1mm=err.apply(lambda e: (e > 1).mean()),
                                    flagged=fr.groupby("plane")["flags"].apply(lambda f: f.notna().mean()))),
                  left_on="plane", right_index=True)
    for k, v in reversed(labels.items()):
        pk.insert(0, k, v)
    return pk


def snr_db(seq) -> float:
    """SNR (dB) of frame 0 of a noisy recording: its noise-free render's power over the noise's."""
    import dataclasses
    noisy = SimulatedSource(seq, PAPER_CAMERA, 4).raw(0).astype(np.float64)
    clean = SimulatedSource(dataclasses.replace(seq, effects=dataclasses.replace(
        seq.effects, full_well_e=None, read_noise_e=None, bit_depth=None)), PAPER_CAMERA, 4).raw(0)
    return float(10 * np.log10(np.sum(clean.astype(np.float64) ** 2) / np.sum((noisy - clean) ** 2)))


def stage_bars(work: Path, fps: float, duration: float) -> tuple[pd.DataFrame, dict]:
    rows, snr = [], {}
    for kind, seed in (("paper", SEED_PAPER), ("overlap", SEED_OVERLAP)):
        for noise in (None, NOISE):
            seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(seed), kind, fps=fps, duration_s=duration,
                                   noise=noise)
            job, truth = simulated_job(seq, PAPER_CAMERA)
            out = work / f"{kind}-{'noise' if noise else 'clean'}"
            t = time.perf_counter()
            run(job, out, truth=truth, progress=False)
            print(f"{kind} {'noise' if noise else 'noise-free'}: {time.perf_counter() - t:.0f} s", flush=True)
            rows.append(_peaks(out, scene=kind, noise="shot+read, 12 bit" if noise else "noise-free",
                               route="shift-sum", fps=fps, n_frames=seq.n_frames))
            if noise:
                snr[kind] = snr_db(seq)
    return pd.concat(rows, ignore_index=True), snr


def stage_reconstruct(work: Path) -> tuple[pd.DataFrame, dict]:
    """The overlap by shift-and-sum (serial) and pd-tv (2 workers), each from scratch (its
    folder deleted first, so the time is not a resume's); their wall times (s)."""
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(SEED_RECON), "overlap", fps=100.0, duration_s=1.0)
    rows, times = [], {}
    for route, workers in (("shift-sum", None), ("reconstruct-pd-tv", 2)):
        job, truth = simulated_job(seq, PAPER_CAMERA, route=route)
        out = work / f"overlap-{route}"
        shutil.rmtree(out, ignore_errors=True)
        t = time.perf_counter()
        s = run(job, out, truth=truth, workers=workers, progress=True)
        times[route] = dict(total_s=time.perf_counter() - t, startup_s=s["startup_s"], workers=workers or 0)
        print(f"overlap {route}: {times[route]['total_s']:.0f} s", flush=True)
        rows.append(_peaks(out, scene="overlap", noise="noise-free", route=route, fps=seq.fps, n_frames=seq.n_frames))
    return pd.concat(rows, ignore_index=True), times


#: The operators stage's routes: (label, route, rays of a traced operator or None for the exact one).
OPERATOR_ROUTES = (("pd-tv, 4-ray traced operator (the earlier default)", "reconstruct-pd-tv", 4),
                   ("pd-tv, exact operator", "reconstruct-pd-tv", None),
                   ("admm, exact operator", "reconstruct-admm", None))


def stage_operators(work: Path, n_frames: int, repeats: int) -> pd.DataFrame:
    """Frames/s of one worker (Dask, one thread) reconstructing the overlap recording's planes
    with each of :data:`OPERATOR_ROUTES`, interleaved, ``repeats`` runs each from scratch; the
    operator's build (once per worker) is part of the task time and reported apart."""
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(SEED_RECON), "overlap", fps=100.0,
                           duration_s=n_frames / 100.0)
    rows = []
    for rep in range(repeats):
        for label, route, rays in OPERATOR_ROUTES:
            job, _ = simulated_job(seq, PAPER_CAMERA, route=route, operator_rays=rays)
            out = work / f"operators-{rep}-{route}-{rays}"
            shutil.rmtree(out, ignore_errors=True)
            s = run(job, out, workers=1, progress=False)
            busy = s["busy_s"]
            rows.append(dict(route=label, repeat=rep, n_frames=s["n_frames"], wall_s=s["wall_s"],
                             frames_per_s=s["frames_per_s"], **{f"{k[:-2]}_ms": 1e3 * v / s["n_frames"]
                                                                for k, v in busy.items()}))
            print(rows[-1], flush=True)
    return pd.DataFrame(rows)


#: The stream stage: recordings (kind, seed) at 100 frames/s, rendered at this many rays per pixel (their own
#: error well below the solves'), and the sensor noise of ``lf-flame sequence --noise`` for the noisy rows.
STREAM_SCENES = (("overlap", SEED_RECON), ("paper", SEED_PAPER))
STREAM_RAYS = 64


def stage_stream(n_frames: int) -> pd.DataFrame:
    """Per frame, the solve time on one thread and the worst plane's error against the truth of admm from
    scratch (``state=None``) and continuing the chunk's previous frame (:meth:`SequenceJob.planes_and_saturated`),
    interleaved, noise-free and with the sensor noise of ``lf-flame sequence --noise``."""
    import numba
    from lf_flame.tomo.truth import scene_truth
    numba.set_num_threads(1)
    rows = []
    for (kind, seed), noise in ((k, n) for k in STREAM_SCENES for n in (None, NOISE)):
        seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(seed), kind, fps=100.0,
                               duration_s=n_frames / 100.0, noise=noise)
        job, _ = simulated_job(seq, PAPER_CAMERA, SimulatedSource(seq, PAPER_CAMERA, STREAM_RAYS),
                               route="reconstruct-admm")
        op = job.operator()
        op.workers = 1                                                    # SciPy's FFTs on one thread too
        knobs = job.reconstruction()
        state = {}
        for i, raw in enumerate(job.source.frames(0, n_frames)):
            views = job.views(raw)
            truth = scene_truth(seq.scene(PAPER_CAMERA, i), op)
            if i % job.chunk == 0:
                state = {}
            row = dict(scene=kind, noise="noise-free" if noise is None else "shot+read, 12 bit", frame=i,
                       admm_noise=knobs.get("admm_noise"), stream_first=not state)
            for mode, st in (("scratch", None), ("stream", state)):
                t0 = time.perf_counter()
                planes, _ = job.planes_and_saturated(views, st)
                row[f"{mode}_s"] = time.perf_counter() - t0
                err = np.linalg.norm((planes - truth).reshape(len(truth), -1), axis=1)
                row[f"{mode}_err"] = float((err / np.linalg.norm(truth.reshape(len(truth), -1), axis=1)).max())
            rows.append(row)
        print(f"  stream {kind} {row['noise']} done", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return pd.DataFrame(rows)


def stream_table(d: pd.DataFrame) -> pd.DataFrame:
    """Per recording: each mode's solve time (median, p90; frames/s per core) and worst-plane error (mean, p90,
    worst) over the frames that continue a solve (each chunk's first is solved from scratch in both)."""
    out = []
    for (scene, noise), g in d.groupby(["scene", "noise"], sort=False):
        g = g[~g.stream_first]
        row = dict(scene=scene, noise=noise, frames=len(g))
        for mode in ("scratch", "stream"):
            row.update({f"{mode}_ms_median": 1e3 * g[f"{mode}_s"].median(),
                        f"{mode}_ms_p90": 1e3 * g[f"{mode}_s"].quantile(0.9),
                        f"{mode}_frames_per_s_core": 1 / g[f"{mode}_s"].median(),
                        f"{mode}_err_mean": g[f"{mode}_err"].mean(), f"{mode}_err_p90": g[f"{mode}_err"].quantile(0.9),
                        f"{mode}_err_worst": g[f"{mode}_err"].max()})
        row["x_faster"] = row["scratch_ms_median"] / row["stream_ms_median"]
        row["share_stream_over_1.1x_scratch"] = float((g.stream_err > 1.1 * g.scratch_err).mean())
        out.append(row)
    return pd.DataFrame(out)


def stage_speed(work: Path, n_frames: int, repeats: int) -> tuple[pd.DataFrame, float]:
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(SEED_PAPER), "paper", fps=500.0,
                           duration_s=n_frames / 500.0)
    h5 = work / "speed.h5"
    if not h5.exists():
        write_frames(h5, SimulatedSource(seq, PAPER_CAMERA, 4), progress=False)
    source, _ = open_source(h5)
    job, _ = simulated_job(seq, PAPER_CAMERA, source)
    old_job = dataclasses.replace(job, source=PerFrameH5(source.path))
    rows, tables = [], {}
    for rep in range(repeats):
        for mode, workers, per_frame in SPEED_MODES:
            out = work / f"speed-{rep}-{workers}-{int(per_frame)}"
            shutil.rmtree(out, ignore_errors=True)
            s = run(old_job if per_frame else job, out, workers=workers, progress=False)
            tables[mode] = (out / "frames.csv").read_bytes()
            busy = s["busy_s"]
            cores = workers or 2
            rows.append(dict(mode=mode, repeat=rep, workers=workers or 0, n_frames=s["n_frames"],
                             startup_s=s["startup_s"], wall_s=s["wall_s"], frames_per_s=s["frames_per_s"],
                             read_ms=1e3 * busy["read_s"] / s["n_frames"],
                             refocus_ms=1e3 * busy["refocus_s"] / s["n_frames"],
                             measure_ms=1e3 * busy["measure_s"] / s["n_frames"],
                             scheduling_ms=1e3 * (cores * s["wall_s"] - sum(busy.values())) / s["n_frames"]
                             if workers else 0.0))
            print(rows[-1], flush=True)
    same = len(set(tables.values())) == 1
    return pd.DataFrame(rows), same


def _snr_text(out: Path) -> str:
    snr = json.loads((out / "sequence.json").read_text()).get("noise", {}).get("snr_db", {})
    return ", ".join(f"SNR {v:.1f} dB on the {k} scene's first frame" for k, v in snr.items()) or "SNR not measured"


def report(out: Path) -> None:
    md = ["# Flame recordings: per-plane flicker", "",
          "Generated by `python experiments/sequence.py` (`make sequence`). Shift-and-sum at the flames' "
          "analytic slopes, `lf_flame.measure.diagnostics.measure_flame` per plane in its flame's column band, "
          "Welch spectra of each plane's height over the whole record (Hann window, bin 1/T). The noisy "
          f"recordings have shot noise for a {NOISE[0]:,.0f} e⁻ full well, {NOISE[1]:g} e⁻ read noise and "
          f"{NOISE[2]} bits ({_snr_text(out)}). 'others below' is how far (dB) the other flames' frequencies lie below the "
          "plane's own on its spectrum (the worst of them; negative: another flame's flicker is stronger).", ""]
    cols = ["scene", "noise", "route", "n_frames", "depth_mm", "true_hz", "dominant_hz", "within_one_bin",
            "others_below_db", "height_err_mm_mean", "height_err_mm_p90", "height_err_mm_max", "share_over_1mm"]
    for name, title in (("sequence.csv", "## Each plane's dominant frequency (1 s at 500 frames/s)"),
                        ("sequence_reconstruct.csv", "## The overlap with each plane's emission (1 s at 100 "
                                                     "frames/s)")):
        if (out / name).exists():
            d = pd.read_csv(out / name).query("signal == 'height_mm'")
            md += [title, "", d[cols].to_markdown(index=False, floatfmt=".3g"), ""]
            times = json.loads((out / "sequence.json").read_text()).get("reconstruct_times")
            if name == "sequence_reconstruct.csv" and times:
                def where(v):
                    return f"{v['workers']} workers" if v["workers"] else "serial"
                md += ["Wall time of each run from scratch on this machine (2 cores, shared with other jobs), "
                       "cluster start included: " + "; ".join(f"{r}: {v['total_s']:.0f} s ({where(v)})"
                                                              for r, v in times.items()) + ".", ""]
    if (out / "sequence_speed.csv").exists():
        sp = pd.read_csv(out / "sequence_speed.csv")
        g = sp.groupby("mode", sort=False)
        t = g[["frames_per_s", "startup_s", "read_ms", "refocus_ms", "measure_ms", "scheduling_ms"]].median()
        t.insert(1, "frames_per_s_runs", g.frames_per_s.apply(lambda v: " / ".join(f"{x:.1f}" for x in v)))
        per_frame = 1.0 / t.loc["Dask, 1 worker", "frames_per_s"]
        two = t.loc["Dask, 2 workers", "frames_per_s"]
        ratio = two / t.loc["Dask, 1 worker", "frames_per_s"]
        meta = json.loads((out / "sequence.json").read_text())
        old = "Dask, 1 worker, one open per frame"
        reading = []
        if old in t.index:
            new_runs = sp[sp["mode"] == "Dask, 1 worker"].frames_per_s.to_numpy()
            old_runs = sp[sp["mode"] == old].frames_per_s.to_numpy()
            reading = [f"- Reading the HDF5 file once per chunk of {meta.get('chunk', 16)} frames instead of once "
                       f"per frame (1 worker, the same frames, interleaved): **{new_runs.mean():.1f}** "
                       f"(runs {' / '.join(f'{v:.1f}' for v in new_runs)}) against **{old_runs.mean():.1f}** "
                       f"(runs {' / '.join(f'{v:.1f}' for v in old_runs)}) frames/s, "
                       f"{new_runs.mean() / old_runs.mean():.2f}x (run by run: "
                       + ", ".join(f"{v:.2f}x" for v in new_runs / old_runs)
                       + f"); reading {t.loc['Dask, 1 worker', 'read_ms']:.1f} against "
                       f"{t.loc[old, 'read_ms']:.1f} ms per frame. The machine (2 cores) was shared with other "
                       "jobs: compare the modes of one run, not the figures across runs."]
        md += ["## What the per-frame work costs", "",
               f"{int(sp.n_frames.iloc[0])} stored frames (HDF5, uint16, lzf) of the paper's four flames, read, "
               "refocused at four planes and measured; medians of the runs (each run's figure in "
               "`frames_per_s_runs`), from the moment the cluster is up (its start: `startup_s`). "
               "Per-frame milliseconds are task time per frame; scheduling is the cores' wall time not spent in "
               "the tasks.", "", t.reset_index().to_markdown(index=False, floatfmt=".3g"), "",
               f"- 2 workers give **{ratio:.2f}x** the frames/s of 1 worker (bar: >= 1.6x); run by run: "
               + ", ".join(f"{v:.2f}x" for v in sp[sp["mode"] == "Dask, 2 workers"].frames_per_s.to_numpy()
                           / sp[sp["mode"] == "Dask, 1 worker"].frames_per_s.to_numpy()) + ".",
               f"- One core (1 worker, 1 thread): **{1 / per_frame:.1f} frames/s** with reading, "
               f"**{1e3 / (t.loc['Dask, 1 worker', 'refocus_ms'] + t.loc['Dask, 1 worker', 'measure_ms']):.1f} "
               "frames/s** for refocusing and diagnostics alone (goal: >= 50).",
               f"- Every mode (serial, Dask, both readings) wrote identical frame tables: {meta['identical_tables']}.",
               *reading,
               f"- A 10,000-frame recording at this cost: {10_000 * per_frame / 60:.1f} core-minutes; at the "
               f"2 workers' {two:.1f} frames/s, {10_000 / two / 60:.1f} min on one 2-core machine, and about "
               f"{10_000 * per_frame / 60 / 16:.1f} min on 8 such machines (16 workers) if they scale as one "
               "worker does, the frames are where the workers can read them and scheduling stays a small share.",
               ""]
    if (out / "sequence_operators.csv").exists():
        op = pd.read_csv(out / "sequence_operators.csv")
        g = op.groupby("route", sort=False)
        t = g[[c for c in op.columns if c.endswith("_ms")] + ["frames_per_s"]].median()
        t.insert(0, "frames_per_s_runs", g.frames_per_s.apply(lambda v: " / ".join(f"{x:.3g}" for x in v)))
        base = t.frames_per_s.iloc[0]
        t["x_before"] = t.frames_per_s / base
        md += ["## Each plane's emission in a recording: the 4-ray traced operator against the exact one", "",
               f"The overlap recording's first {int(op.n_frames.iloc[0])} frames (100 frames/s, three planes), "
               "reconstructed by one Dask worker (one thread), the routes interleaved, each run from scratch "
               "(`python experiments/sequence.py --stage operators`); the operator is built once per worker, "
               "inside the first frame's task time (`refocus_ms`: the planes' work, here the solve). The machine "
               "was shared with other jobs: compare the rows of one run. Medians of the runs:", "",
               t.reset_index().to_markdown(index=False, floatfmt=".3g"), ""]
    if (out / "sequence_stream.csv").exists():
        st = stream_table(pd.read_csv(out / "sequence_stream.csv"))
        md += ["## Each plane's emission frame after frame: continuing the previous frame's solve", "",
               f"Recordings at 100 frames/s rendered at {STREAM_RAYS} rays per pixel, each frame's planes by admm on "
               "one thread (the exact operator, the lenslet grid, the knobs of the first frame's noise), from scratch "
               "against continuing the chunk's previous frame (at most "
               "`lf_flame.tomo.defaults.ADMM_STREAM_FILLS` fills), interleaved frame by frame "
               "(`python experiments/sequence.py --stage stream`); errors are the worst plane's relative L2 error "
               "against the truth, over the frames that continue a solve. The machine was shared: compare the "
               "columns of one row.", "", st.to_markdown(index=False, floatfmt=".3g"), ""]
    md += ["![paper recording](sequence.png)", "", "![overlap recording](sequence_overlap.png)", ""]
    if (out / "sequence_overlap_reconstruct.png").exists():
        md += ["![overlap, each plane's emission](sequence_overlap_reconstruct.png)", ""]
    atomic_write_text(out / "sequence.md", "\n".join(md))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default="results")
    p.add_argument("--work", default="data/sequence", help="recordings and per-run folders (not in git)")
    p.add_argument("--stage", choices=["all", "bars", "speed", "reconstruct", "operators", "stream", "report"],
                   default="all")
    p.add_argument("--fps", type=float, default=500.0)
    p.add_argument("--duration", type=float, default=1.0)
    p.add_argument("--speed-frames", type=int, default=320)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--operator-frames", type=int, default=8, help="frames of the operators stage")
    p.add_argument("--stream-frames", type=int, default=32, help="frames of each recording of the stream stage")
    a = p.parse_args(argv)
    out, work = Path(a.out), Path(a.work)
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    meta_path = out / "sequence.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    if a.stage in ("all", "bars"):
        d, snr = stage_bars(work, a.fps, a.duration)
        atomic_write_text(out / "sequence.csv", d.to_csv(index=False, float_format="%.6g"))
        shutil.copy(work / "paper-clean" / "sequence.png", out / "sequence.png")
        shutil.copy(work / "overlap-clean" / "sequence.png", out / "sequence_overlap.png")
        meta.update(seeds=dict(paper=SEED_PAPER, overlap=SEED_OVERLAP), fps=a.fps, duration_s=a.duration,
                    noise=dict(full_well_e=NOISE[0], read_noise_e=NOISE[1], bit_depth=NOISE[2], snr_db=snr))
    if a.stage in ("all", "speed"):
        d, same = stage_speed(work, a.speed_frames, a.repeats)
        atomic_write_text(out / "sequence_speed.csv", d.to_csv(index=False, float_format="%.6g"))
        meta.update(identical_tables=same, speed_frames=a.speed_frames, chunk=CHUNK)
    if a.stage == "reconstruct":
        d, times = stage_reconstruct(work)
        atomic_write_text(out / "sequence_reconstruct.csv", d.to_csv(index=False, float_format="%.6g"))
        meta.update(reconstruct_times=times)
        shutil.copy(work / "overlap-reconstruct-pd-tv" / "sequence.png", out / "sequence_overlap_reconstruct.png")
        meta.update(reconstruct_seed=SEED_RECON)
    if a.stage == "operators":
        d = stage_operators(work, a.operator_frames, a.repeats)
        atomic_write_text(out / "sequence_operators.csv", d.to_csv(index=False, float_format="%.6g"))
        meta.update(operator_frames=a.operator_frames, operators_seed=SEED_RECON)
    if a.stage == "stream":
        d = stage_stream(a.stream_frames)
        atomic_write_text(out / "sequence_stream.csv", d.to_csv(index=False, float_format="%.6g"))
        meta.update(stream_frames=a.stream_frames, stream_rays=STREAM_RAYS, stream_scenes=STREAM_SCENES)
    if a.stage != "report":
        meta.setdefault("wall_s", {})[a.stage] = time.perf_counter() - t0
        meta.update(provenance=provenance(), command=" ".join(sys.argv))
        atomic_write_text(meta_path, json.dumps(meta, indent=1, default=float))
    report(out)


if __name__ == "__main__":
    main()
