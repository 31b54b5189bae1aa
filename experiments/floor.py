"""Each emission route's time as a multiple of this machine's floor, and where admm's time goes.

The floor (what no route on the exact operator can undercut): the paper camera's lit views read once into
their FFT canvas (float32) and one batched real FFT of all of them, forward and back
(``scipy.fft.rfft2`` / ``irfft2``), on two threads (the routes' setting) and on one (a recording's
worker). Every route is timed on the same light fields in the same process and reported as a multiple of
that floor:

- ``admm, 2 x 2 grid``: ``reconstruct(views, op, "admm")`` on the exact operator with 2 x 2 samples per
  lenslet (the package's default for 4 planes), the paper's, varied and overlap renders of
  ``make fourier-solver`` (``data/fourier_solver``, 400 rays per pixel), noise-free and at 14 dB;
- ``admm, lenslet grid``: the same on the lenslet grid;
- ``depths found and solved``: :func:`lf_flame.tomo.found_planes.find_planes` (the depth route of
  ``lf-flame reconstruct``), the paper's render;
- ``recording frame``: one frame of the paper's flame recording at 100 frames/s continuing the previous
  frame's solve (``lf-flame sequence --route reconstruct-admm``; one thread, against the one-thread floor);
- ``shift-and-sum``: ``focal_stack`` at the four planes' slopes.

``--compare DIR`` times the routes of another checkout of the package (``PYTHONPATH=DIR``, e.g. a
``git worktree`` of the commit before a change) in child processes that alternate with this one's
(A B A B ...), so that the machine's drift falls on both. The children time the same light fields, which this
checkout saves first (:data:`INPUTS`), through the package's public names only, so that a much older checkout can
be compared too; a route that version cannot run is left out of its rows (its ``x_faster`` blank). ``--stage profile`` splits admm's solve (2 x 2
grid, paper render) and a recording frame into its stages by wrapping the solver's kernels and FFT calls
(the wrappers' own cost, microseconds per call, goes to "rest").

Writes ``<out>/floor.{csv,md,json}``. Usage: ``python experiments/floor.py --out results [--pairs 4]
[--repeats 5] [--compare DIR]``; needs ``data/fourier_solver`` (``python experiments/fourier_solver.py``
renders and caches it on first use).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from alternating import Clock, alternate, compared_commit  # noqa: E402

CACHE = ROOT / "data" / "fourier_solver"
#: The light fields the children time (:func:`write_inputs`).
INPUTS = CACHE / "floor_inputs.npz"
#: The exact operator's precision (``fourier_solver.py``'s).
PRECISION = "float32"
KINDS = ("paper", "varied", "overlap")
#: Rays per pixel of the scored renders (``fourier_solver.py``'s default, its cache's).
RAYS = 400
#: The recording of the ``recording frame`` route: frames rendered at this many rays per pixel (the time does not
#: depend on the render's own error), the first starting the solve.
STREAM_FRAMES, STREAM_RAYS = 10, 16


def floor_s(op, views, workers: int, repeats: int) -> list:
    """Seconds of: the lit views read into a zeroed float32 canvas, one batched rfft2 and irfft2 of them."""
    import scipy.fft
    N, _, R, C = op.dimsd
    lit, canvas = op._lit, op.canvas_shape
    flat = np.asarray(views).reshape(N * N, R, C)
    out = []
    for _ in range(repeats + 1):
        t0 = time.perf_counter()
        z = np.zeros((len(lit),) + canvas, np.float32)
        z[:, :R, :C] = flat[lit]
        scipy.fft.irfft2(scipy.fft.rfft2(z, workers=workers), s=canvas, workers=workers)
        out.append(time.perf_counter() - t0)
    return out[1:]


def timed(f, repeats: int) -> list:
    f()                                                            # warm-up: Numba's kernels, the operator's factors
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        out.append(time.perf_counter() - t0)
    return out


def recording(n_frames: int = STREAM_FRAMES):
    """The paper's flame recording at 100 frames/s as ``lf-flame sequence`` solves it: (job, frames' views)."""
    import sequence as S
    from lf_flame.optics.camera import PAPER_CAMERA
    seq = S.flicker_sequence(PAPER_CAMERA, np.random.default_rng(S.SEED_PAPER), "paper", fps=100.0,
                             duration_s=n_frames / 100.0, noise=None)
    job, _ = S.simulated_job(seq, PAPER_CAMERA, S.SimulatedSource(seq, PAPER_CAMERA, STREAM_RAYS),
                             route="reconstruct-admm")
    return job, [job.views(r) for r in job.source.frames(0, n_frames)]


def stream_times(job, frames) -> list:
    """Seconds per frame of the frames after the first, each continuing the previous frame's solve, on one
    thread (Numba's and SciPy's)."""
    import numba
    numba.set_num_threads(1)
    op = job.operator()
    workers, op.workers = op.workers, 1
    try:
        state, out = {}, []
        for i, views in enumerate(frames):
            t0 = time.perf_counter()
            job.planes_and_saturated(views, state)
            if i:
                out.append(time.perf_counter() - t0)
        return out
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        op.workers = workers


def write_inputs() -> None:
    """Save the light fields every child times to :data:`INPUTS` (this checkout's renders, read from or added to
    ``data/fourier_solver``): the paper's, varied and overlap renders, noise-free and at 14 dB, and their planes'
    depths. A child of another checkout (``--compare``) reads them with NumPy alone, so it needs nothing of this
    checkout's experiments."""
    import fourier_solver as F
    import reconstruct as R
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    arrays = {}
    for kind in KINDS:
        scene, clean, noisy, _, _ = F.render_set(cam, kind, R.TEST_SEEDS[0], RAYS, CACHE)
        arrays.update({f"{kind}_noise-free": clean, f"{kind}_14 dB": noisy,
                       f"{kind}_depths": np.asarray(R.planes_of(kind, scene), float)})
    tmp = INPUTS.with_name(INPUTS.name + ".part.npz")
    np.savez(tmp, **arrays)
    tmp.replace(INPUTS)


def child(repeats: int) -> None:
    """Time the floor and every route on the light fields of :data:`INPUTS`; print one JSON row per timed call.
    Only the package's public names are used, so that a checkout of another version (``--compare``) times the same
    calls; a route its version cannot run (the recording's job, whose interface changed) is left out, with a line
    on standard error."""
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack
    from lf_flame.tomo import ExactOperator, find_planes, reconstruct

    def emit(route, scene, noise, times, threads=2):
        for t in times:
            print(json.dumps(dict(route=route, scene=scene, noise=noise, threads=threads, time_s=t)), flush=True)
    data = np.load(INPUTS)
    for kind in KINDS:
        clean, depths = data[f"{kind}_noise-free"], [float(d) for d in data[f"{kind}_depths"]]
        fine = ExactOperator(cam, depths, precision=PRECISION, subsamples=2)
        coarse = ExactOperator(cam, depths, precision=PRECISION)
        if kind == "paper":
            emit("floor", kind, "-", floor_s(fine, clean, 2, repeats))
            emit("floor", kind, "-", floor_s(fine, clean, 1, repeats), threads=1)
        for noise in ("noise-free", "14 dB"):
            views = data[f"{kind}_{noise}"]
            emit("admm, 2 x 2 grid", kind, noise, timed(lambda: reconstruct(views, fine, "admm"), repeats))
            emit("admm, lenslet grid", kind, noise, timed(lambda: reconstruct(views, coarse, "admm"), repeats))
        if kind == "paper":
            emit("depths found and solved", kind, "noise-free", timed(lambda: find_planes(clean, cam), 2))
            slopes = [cam.slope_for_depth(d) for d in depths]
            mask = aperture_mask(cam.pixels_per_lenslet, "circular")
            emit("shift-and-sum", kind, "noise-free", timed(lambda: focal_stack(clean, slopes, mask), repeats))
        print(f"  {kind} done", file=sys.stderr, flush=True)
    try:
        job, frames = recording()
        times = stream_times(job, frames)
    except (ImportError, AttributeError, TypeError) as e:       # another version's recording interface
        print(f"  recording frame not timed in this version: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
    else:
        emit("recording frame", "paper recording", "noise-free", times, threads=1)


def profile(repeats: int) -> list:
    """Rows (case, stage, seconds per solve, share) of admm's 2 x 2 grid solve of the paper's render and of a
    recording frame, from wrappers on the solver's FFT calls and kernels."""
    import scipy.fft

    import fourier_solver as F
    import reconstruct as R
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.tomo import _exact_kernels as EK
    from lf_flame.tomo import _fourier_kernels as K
    from lf_flame.tomo.exact import ExactOperator
    from lf_flame.tomo.fourier_system import FourierSystem
    from lf_flame.tomo.solvers import reconstruct
    scene, clean, noisy, _, _ = F.render_set(cam, "paper", R.TEST_SEEDS[0], RAYS, CACHE)
    fine = ExactOperator(cam, R.planes_of("paper", scene), precision=F.PRECISION, subsamples=2)
    job, frames = recording()
    n_views = {len(fine._lit), len(job.operator()._lit)}
    clock = Clock()
    fft = lambda args: "FFTs of the views (batched)" if np.shape(args[0])[0] in n_views else "FFTs of the planes"
    patched = [clock.wrap(scipy.fft, "rfft2", fft), clock.wrap(scipy.fft, "irfft2", fft)]
    patched += [clock.wrap(K, n, "spectra products (H, H^H)") for n in ("spectra_forward", "spectra_adjoint")]
    patched += [clock.wrap(EK, n, "sums over the taps (H, H^H)")
                for n in ("taps_forward", "taps_adjoint", "taps_adjoint_columns", "column_sums")]
    patched += [clock.wrap(K, n, "data gather and fills") for n in ("gather_data", "fill")]
    patched += [clock.wrap(K, n, "ADMM steps (target, projection, TV)") for n in ("admm_target", "admm_project",
                                                                                  "tv_shrink")]
    patched += [clock.wrap(FourierSystem, "solve", "per-frequency solves")]
    rows = []
    try:
        for case, f, n in (("admm, 2 x 2 grid, paper render, noise-free", lambda: reconstruct(clean, fine, "admm"),
                            repeats),
                           ("admm, 2 x 2 grid, paper render, 14 dB", lambda: reconstruct(noisy, fine, "admm"), repeats),
                           ("recording frame (one thread)", lambda: stream_times(job, frames), 1)):
            f()
            clock.s.clear()
            t0 = time.perf_counter()
            for _ in range(n):
                f()
            total = time.perf_counter() - t0
            per = n * (len(frames) if case.startswith("recording") else 1)
            rest = total - sum(clock.s.values())
            for stage, s in sorted(clock.s.items(), key=lambda kv: -kv[1]) + [("rest (Python, copies, allocation)",
                                                                               rest)]:
                rows.append(dict(case=case, stage=stage, ms_per_solve=1e3 * s / per, share=s / total))
    finally:
        for owner, name, f in patched:
            setattr(owner, name, f)
    return rows


def summary(df, floors):
    """Per version, route, scene and noise: the median, 90th percentile and worst time, and the median as a
    multiple of the floor of its thread count (the floor's median over the version's children)."""
    g = df.groupby(["version", "route", "scene", "noise", "threads"]).time_s
    tab = g.agg(n="count", median_s="median", p90_s=lambda t: float(np.percentile(t, 90)), worst_s="max").reset_index()
    tab["x_floor"] = [r.median_s / floors[(r.version, r.threads)] for r in tab.itertuples()]
    return tab


def main(argv=None) -> int:
    import pandas as pd

    from lf_flame.config import atomic_write_text, provenance
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--pairs", type=int, default=4, help="child processes per version")
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per route and child")
    ap.add_argument("--compare", type=Path, default=None, help="another checkout's root, timed as 'before'")
    ap.add_argument("--stage", choices=("all", "routes", "profile", "report"), default="all",
                    help="report: the markdown again from floor.json")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a.repeats)
        return 0
    t_all = time.perf_counter()
    a.out.mkdir(parents=True, exist_ok=True)
    meta_path = a.out / "floor.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    if a.stage == "report":
        write_md(a.out, meta)
        return 0
    versions = {"this checkout": None} if a.compare is None else {"before": a.compare.resolve(), "after": None}
    if a.stage in ("all", "routes"):
        write_inputs()
        pypath = lambda path: os.pathsep.join([str(path)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
        rows = alternate(__file__, ["--out", a.out, "--repeats", a.repeats],
                         {name: {} if path is None else {"PYTHONPATH": pypath(path)}
                          for name, path in versions.items()},
                         a.pairs, "version", reverse_odd=True)
        df = pd.DataFrame(rows)
        fl = df[df.route == "floor"].groupby(["version", "threads"]).time_s.median()
        tab = summary(df[df.route != "floor"], fl.to_dict())
        if a.compare is not None:
            tab = versus(tab, df[df.route != "floor"])
        atomic_write_text(a.out / "floor.csv", df.to_csv(index=False, float_format="%.6g"))
        compared = compared_commit(a.compare)
        meta.update(routes=dict(pairs=a.pairs, repeats=a.repeats, compare=None if a.compare is None else str(a.compare),
                                compare_commit=compared or None,
                                floor_s={f"{v}, {t} thread{'s' if t > 1 else ''}": float(t_s)
                                         for (v, t), t_s in fl.items()},
                                floor_p90_s={f"{v}, {t}": float(np.percentile(g, 90)) for (v, t), g in
                                             df[df.route == "floor"].groupby(["version", "threads"]).time_s},
                                table=tab.to_dict(orient="records"), wall_s=time.perf_counter() - t_all))
    if a.stage in ("all", "profile"):
        t0 = time.perf_counter()
        meta["profile"] = dict(rows=profile(a.repeats), wall_s=time.perf_counter() - t0)
    meta["provenance"] = provenance()
    atomic_write_text(meta_path, json.dumps(meta, indent=1, default=float))
    write_md(a.out, meta)
    return 0


def versus(tab, df):
    """``after``'s rows of :func:`summary`'s ``tab`` with ``before``'s median beside them, the ratio of the two medians
    (``x_faster``) and its range over the pairs of children (``x_faster_pairs``, the machine's drift between them):
    blank (NaN, "–") for a route the ``before`` version could not run."""
    key = ["route", "scene", "noise"]
    after = tab[tab.version == "after"].set_index(key)
    before = tab[tab.version == "before"].set_index(key).median_s.reindex(after.index)
    per = df.groupby(key + ["pair", "version"]).time_s.median().unstack("version")
    spread = (per["before"] / per["after"]).groupby(key).agg(["min", "max"]).reindex(after.index)
    return after.assign(before_median_s=before, x_faster=before / after.median_s,
                        x_faster_pairs=["–" if np.isnan(lo) else f"{lo:.2f}-{hi:.2f}" for lo, hi in spread.values]
                        ).reset_index().drop(columns="version")


def write_md(out: Path, meta) -> None:
    import pandas as pd

    from lf_flame.config import atomic_write_text
    md = ["# Each route's time as a multiple of the floor (`python experiments/floor.py`)", "",
          "The floor: the paper camera's lit views read once into their FFT canvas (float32) and one batched real "
          "FFT of all of them, forward and back; on two threads (the routes' setting) and on one (a recording's "
          "worker, against which the recording frame is measured). Every route timed in the same child processes "
          "as the floor; the machine (2 cores) is shared: compare rows of one run."]
    if "routes" in meta:
        r = meta["routes"]
        floors = ", ".join(f"{k}: {1e3 * v:.1f} ms" for k, v in r["floor_s"].items())
        md += ["", f"{r['pairs']} child processes per version, {r['repeats']} timed calls per route in each "
               f"({r['wall_s']:.0f} s). Floor medians: {floors}."
               + ("" if not r["compare"] else " `before`: the checkout given by `--compare`"
                  + (f" (commit {r['compare_commit']})" if r.get("compare_commit") else "") + ", its children "
                  "alternating with this one's; `x_faster`: before's median over after's, `x_faster_pairs` the "
                  "same per pair of children (the machine's drift between them)."), "",
               pd.DataFrame(r["table"]).to_markdown(index=False, floatfmt=".3g")]
    if "profile" in meta:
        p = pd.DataFrame(meta["profile"]["rows"])
        md += ["", "## Where the time goes", "",
               "Wrappers on the solver's FFT calls and kernels (`--stage profile`; a recording frame per frame, "
               "the chunk's first frame, solved from scratch, among them):", "",
               p.to_markdown(index=False, floatfmt=".3g")]
    atomic_write_text(out / "floor.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    raise SystemExit(main())
