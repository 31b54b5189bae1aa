"""A user's capture from its raw file to found depths and emission planes in one command: the command's wall time.

The camera of ``examples/own_camera.toml`` (150 µm lenslets, 10.57 px lenslet images, rotated 0.4°) on a
1080 x 1080 sensor: 99 x 98 lenslets. Set-up, through the command line: its white image (``simulate --scene
white``) -> ``calibrate``; one depth scene (``simulate --scene depth``, seed 3). Timed: ``lf-flame reconstruct
RAW --camera CAM --calibration CAL --out OUT`` (decoded on the fly, depths found, admm on the exact operator, the
figure), and the same with ``--no-figure``, each a whole process (the interpreter's start, imports, numba's cache,
the work), in child processes alternating with another checkout's (``--compare DIR``, ``PYTHONPATH=DIR``) so that
the machine's drift falls on both; and a recording of the same camera (30 frames, two flames) through ``lf-flame
sequence`` with the calibration and its white image (each frame decoded), by shift-and-sum and by admm, its
frames/s as the command reports them. Python's bytecode cache is on (``PYTHONDONTWRITEBYTECODE`` unset: an installed
package has its bytecode), after one warm-up run per version and variant. Then one run per version in-process,
its steps timed by wrappers: the imports before the command, reading and decoding the capture, the depth search,
the solves (the first, then the residual's search and refinement), the HDF5, the figure, numba's cache loads
(inside the steps) and the rest.

Writes ``<out>/one_command.{csv,md,json}``. Usage: ``python experiments/one_command.py --out results
[--compare DIR] [--pairs 5]`` (about 6 min on 2 cores with 5 pairs, 9 with 8).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from alternating import Clock, alternate, compared_commit  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SENSOR = (1080, 1080)
SEED = 3
VARIANTS = {"figure": [], "no figure": ["--no-figure"]}
#: A recording of the same camera (``simulate-sequence --simulate overlap``: two flames one behind the other, 30 frames
#: at 100 frames/s), each frame decoded with the calibration and its white image, at the flames' depths: the route.
RECORDING = dict(fps=100, duration=0.3)
RECORDING_ROUTES = {"recording, shift-sum": "shift-sum", "recording, admm": "reconstruct-admm"}


def camera_file(work: Path) -> Path:
    """``examples/own_camera.toml`` with a sensor of :data:`SENSOR` pixels."""
    text = (ROOT / "examples" / "own_camera.toml").read_text()
    rows, cols = SENSOR
    text = text.replace("rows = 520", f"rows = {rows}").replace("cols = 340", f"cols = {cols}")
    assert f"rows = {rows}" in text and f"cols = {cols}" in text
    path = work / "camera.toml"
    path.write_text(text)
    return path


def set_up(work: Path) -> list:
    """The camera file, its calibration and a capture; returns the timed command's arguments (less ``--out``)."""
    work.mkdir(parents=True, exist_ok=True)
    cam = camera_file(work)
    cli = [sys.executable, "-m", "lf_flame.cli"]
    for args in (["simulate", "--scene", "white", "--camera", cam, "--out", work / "white.npz"],
                 ["calibrate", work / "white.npz", "--camera", cam, "--out", work / "calibration.json"],
                 ["simulate", "--scene", "depth", "--seed", SEED, "--camera", cam, "--out", work / "capture.npz"],
                 ["simulate-sequence", "--simulate", "overlap", "--fps", RECORDING["fps"], "--duration",
                  RECORDING["duration"], "--camera", cam, "--quiet", "--out", work / "frames.h5"]):
        subprocess.run(cli + [str(v) for v in args], check=True, capture_output=True, cwd=work)
    return ["reconstruct", str(work / "capture.npz"), "--camera", str(cam), "--calibration",
            str(work / "calibration.json")]


def run_once(args: list, out: Path) -> tuple:
    """``(wall_s, returncode)`` of one ``lf-flame`` process."""
    t = time.perf_counter()
    rc = subprocess.run([sys.executable, "-m", "lf_flame.cli", *args, "--out", str(out)], capture_output=True,
                        cwd=out.parent).returncode        # not the repository: ``-m`` puts the cwd before PYTHONPATH
    return time.perf_counter() - t, rc


def child(work: Path, args: list, phases: bool) -> None:
    """Each variant's whole-process time (one JSON line each); with ``phases`` instead one run in this process with
    its steps timed."""
    if phases:
        print(json.dumps(dict(kind="phases", **phase_times(args + ["--out", str(work / "phases.h5")]))), flush=True)
        return
    for variant, extra in VARIANTS.items():
        out = work / f"rec_{os.getpid()}.h5"
        wall, rc = run_once(args + extra, out)
        out.unlink(missing_ok=True)
        out.with_suffix(".png").unlink(missing_ok=True)
        if rc == 2 and extra:          # a checkout without the option
            continue
        if rc != 0:
            raise SystemExit(f"lf-flame {' '.join(args + extra)} exited {rc}")
        print(json.dumps(dict(kind="process", variant=variant, wall_s=wall)), flush=True)
    for variant, route in RECORDING_ROUTES.items():
        out = work / f"seq_{os.getpid()}"
        argv = ["sequence", str(work / "frames.h5"), "--camera", str(work / "camera.toml"), "--calibration",
                str(work / "calibration.json"), "--white", str(work / "white.npz"), "--route", route, "--quiet"]
        wall, rc = run_once(argv, out)
        if rc != 0:
            raise SystemExit(f"lf-flame {' '.join(argv)} exited {rc}")
        fps = json.loads((out / "summary.json").read_text())["frames_per_s"]
        shutil.rmtree(out)
        print(json.dumps(dict(kind="process", variant=variant, wall_s=wall, frames_per_s=fps)), flush=True)


def phase_times(argv: list) -> dict:
    """One ``lf-flame`` command in this process, its steps timed by wrappers on the command line's functions
    (seconds; ``numba_cache_s`` overlaps them)."""
    import contextlib
    import io
    t0 = time.perf_counter()
    import lf_flame.cli as cli
    import lf_flame.cli.planes as planes
    import lf_flame.cli.volume as vol
    import lf_flame.tomo.files as files
    import numba.core.dispatcher as dispatcher
    t_import = time.perf_counter() - t0
    clock = Clock()
    clock.wrap(dispatcher.Dispatcher, "_compile_for_args", "numba_cache_s")        # numba's cache loads
    for module, name, step in ((vol, "reconstruct_input", "read_and_decode_s"), (vol, "found_planes", "depths_s"),
                               (planes, "run_reconstruction", "first_solve_s"), (vol, "solve_found", "solves_s"),
                               (files, "save_reconstruction", "hdf5_s"), (files, "plot_reconstruction", "figure_s")):
        clock.wrap(module, name, step)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = cli.main(argv)
    total = time.perf_counter() - t0
    if rc not in (0, None):
        raise SystemExit(f"lf-flame {' '.join(argv)} exited {rc}")
    spent = dict(clock.s)
    spent.setdefault("numba_cache_s", 0.0)
    spent["residual_search_and_refine_s"] = spent.get("solves_s", 0.0) - spent.get("first_solve_s", 0.0)
    steps = ("read_and_decode_s", "depths_s", "solves_s", "hdf5_s", "figure_s")
    return dict(imports_s=t_import, **spent, total_in_process_s=total,
                rest_s=total - t_import - sum(spent.get(s, 0.0) for s in steps))


def main(argv=None) -> int:
    import numpy as np
    import pandas as pd

    from lf_flame.config import atomic_write_text, provenance
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--work", type=Path, default=ROOT / "data" / "one_command", help="the camera, calibration and "
                    "capture (made once)")
    ap.add_argument("--pairs", type=int, default=5, help="rounds over the versions")
    ap.add_argument("--compare", type=Path, default=None, help="another checkout's root, timed as 'before'")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--phases", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    cmd = ["reconstruct", str(a.work / "capture.npz"), "--camera", str(a.work / "camera.toml"), "--calibration",
           str(a.work / "calibration.json")]
    if a.child:
        child(a.work, cmd, a.phases)
        return 0
    t_all = time.perf_counter()
    a.out.mkdir(parents=True, exist_ok=True)
    cmd = set_up(a.work)
    pypath = lambda path: os.pathsep.join([str(path)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    versions = {"this checkout": {}} if a.compare is None else {
        "before": {"PYTHONPATH": pypath(a.compare.resolve())}, "after": {}}
    settings = {name: dict(env, PYTHONDONTWRITEBYTECODE=None) for name, env in versions.items()}
    forward = ["--out", a.out, "--work", a.work]
    alternate(__file__, forward, settings, 1, "version")                       # warm-up: bytecode, numba's cache
    rows = alternate(__file__, forward, settings, a.pairs, "version", reverse_odd=True)
    rows += alternate(__file__, forward + ["--phases"], settings, 1, "version")
    df = pd.DataFrame([r for r in rows if r["kind"] == "process"])
    tab = (df.groupby(["variant", "version"]).wall_s.agg(n="size", median_s="median",
                                                           p90_s=lambda s: s.quantile(0.9), worst_s="max")
           .reset_index())
    fps = df.groupby(["variant", "version"]).frames_per_s.agg(["median", "min"])
    tab["frames_per_s_median"] = [fps["median"].get((v, ver), np.nan) for v, ver in zip(tab.variant, tab.version)]
    tab["frames_per_s_min"] = [fps["min"].get((v, ver), np.nan) for v, ver in zip(tab.variant, tab.version)]
    if a.compare is not None:
        per = df.pivot_table(index=["variant", "pair"], columns="version", values="wall_s")
        ratio = (per["before"] / per["after"]).dropna().groupby("variant")
        medians = tab.set_index(["variant", "version"]).median_s
        tab["x_faster"] = [medians.get((v, "before"), np.nan) / m if ver == "after" else np.nan
                           for v, ver, m in zip(tab.variant, tab.version, tab.median_s)]
        tab["x_faster_pairs"] = [f"{ratio.min()[v]:.2f}-{ratio.max()[v]:.2f}" if ver == "after" and v in ratio.groups
                                 else "" for v, ver in zip(tab.variant, tab.version)]
    phases = pd.DataFrame([{k: v for k, v in r.items() if k not in ("kind", "pair")} for r in rows
                           if r["kind"] == "phases"]).set_index("version").T
    compared = compared_commit(a.compare)
    meta = dict(command="lf-flame " + " ".join(Path(c).name if str(a.work) in c else c for c in cmd) + " --out OUT",
                sensor=SENSOR, seed=SEED, pairs=a.pairs,
                recording=(f"a recording of the same camera (simulate-sequence --simulate overlap: two flames, "
                           f"{int(RECORDING['fps'] * RECORDING['duration'])} frames at {RECORDING['fps']} frames/s)"),
                compare=None if a.compare is None else str(a.compare), compare_commit=compared or None,
                wall_s=time.perf_counter() - t_all, table=tab.to_dict("records"), phases=phases.to_dict(),
                provenance=provenance())
    atomic_write_text(a.out / "one_command.csv", df.to_csv(index=False))
    atomic_write_text(a.out / "one_command.json", json.dumps(meta, indent=1, default=str))
    write_md(a.out, meta, tab, phases)
    print(tab.to_string(index=False))
    print(phases.round(3).to_string())
    return 0


def write_md(out: Path, meta: dict, tab, phases) -> None:
    from lf_flame.config import atomic_write_text
    before = "" if not meta["compare"] else (
        f" `before`: the checkout given by `--compare` (commit {meta['compare_commit'] or '?'}), its "
        "children alternating with this one's; `x_faster`: before's median over after's, `x_faster_pairs` the same "
        "per pair of runs (the machine's drift between them).")
    lines = ["# A user's capture to its planes in one command", "",
             "`python experiments/one_command.py --out results"
             + (" --compare DIR" if meta["compare"] else "") + f"` ({meta['wall_s']:.0f} s). The camera of "
             f"`examples/own_camera.toml` on a {meta['sensor'][0]} x {meta['sensor'][1]} sensor (99 x 98 lenslets), "
             f"its white image calibrated, one depth scene (seed {meta['seed']}); timed, as a whole process: "
             f"`{meta['command']}` (decoded on the fly, depths found, admm), with and without `--no-figure`, "
             f"{meta['pairs']} runs per version and variant, Python's bytecode cache on, after a warm-up run. "
             f"The recording variants: `lf-flame sequence frames.h5 --camera camera.toml --calibration "
             f"calibration.json --white white.npz --route ROUTE` on {meta['recording']}, each frame decoded; "
             "`frames_per_s` is the command's own figure (the frames over its chunks' time)." + before,
             "", tab.to_markdown(index=False, floatfmt=".3g"), "",
             "## Where one run's time goes (seconds, in-process, the figure drawn)", "",
             "One run per version; wrappers on the command line's steps. The interpreter's own start (about 0.05 s) "
             "is not in it; `solves_s` holds `first_solve_s` and `residual_search_and_refine_s`; numba's cache loads "
             "(the first of them about 0.3 s: numba's own start) fall inside the steps, and so do the imports a step "
             "makes when it first needs a module (a module no longer imported at the start is imported by the step "
             "that uses it).", "", phases.to_markdown(floatfmt=".3f"), "",
             f"Provenance: {json.dumps(meta['provenance'], default=str)[:1500]}", ""]
    atomic_write_text(out / "one_command.md", "\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
