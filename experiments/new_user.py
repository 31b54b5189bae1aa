"""A new user's quick start, run as the README tells it: each command's time and each route's flame heights.

Runs the README's quick-start commands through the command line itself, in one empty folder
(the relative paths as the README gives them), ``--repeats`` times each in turn:

    lf-flame simulate --scene flame --out flame.npz
    lf-flame refocus flame.npz --depth 20 --depth 10 --depth 0 --depth -10 --out planes.png
    lf-flame reconstruct flame.npz --out volume.h5
    lf-flame profiles flame.npz --out prof
    lf-flame profiles flame.npz --route shift-sum --out prof_shift-sum
    lf-flame simulate-sequence --fps 100 --duration 0.5 --out rec.h5
    lf-flame sequence rec.h5 --out seq/
    lf-flame simulate --scene furnace --temperature T --out bbT.npz      (T = 1600, 2000, 2400)
    lf-flame calibrate-temperature bb1600.npz bb2000.npz bb2400.npz --temperature ... --out bb.json
    lf-flame simulate --scene colour-flame --out colour.npz
    lf-flame temperature colour.npz --calibration bb.json --out T.h5

and writes ``<out>/new_user.md`` (each command's wall time: median and worst of the repeats, as a
whole process on this machine) and ``<out>/new_user.csv`` (the last run's flame heights per route,
``profiles``' default route, admm, and ``shift-sum``, against the scene's truth), with the package
versions.

Usage: ``python experiments/new_user.py --out results [--repeats 2]`` (``make new-user``).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text, provenance

FURNACE_K = (1600, 2000, 2400)
#: The README's quick start, in its order (``lf-flame`` left out).
COMMANDS = (
    ["simulate", "--scene", "flame", "--out", "flame.npz"],
    ["refocus", "flame.npz", "--depth", "20", "--depth", "10", "--depth", "0", "--depth", "-10", "--out", "planes.png"],
    ["reconstruct", "flame.npz", "--out", "volume.h5"],
    ["profiles", "flame.npz", "--out", "prof"],
    ["profiles", "flame.npz", "--route", "shift-sum", "--out", "prof_shift-sum"],
    ["simulate-sequence", "--fps", "100", "--duration", "0.5", "--out", "rec.h5"],
    ["sequence", "rec.h5", "--out", "seq/"],
    *(["simulate", "--scene", "furnace", "--temperature", str(t), "--out", f"bb{t}.npz"] for t in FURNACE_K),
    ["calibrate-temperature", *(f"bb{t}.npz" for t in FURNACE_K),
     *(a for t in FURNACE_K for a in ("--temperature", str(t))), "--out", "bb.json"],
    ["simulate", "--scene", "colour-flame", "--out", "colour.npz"],
    ["temperature", "colour.npz", "--calibration", "bb.json", "--out", "T.h5"],
)
#: ``profiles``' outputs per route: the default route (admm) and shift-and-sum.
PROFILES = {"admm (default)": "prof.csv", "shift-sum": "prof_shift-sum.csv"}
LF = [sys.executable, "-m", "lf_flame.cli"]


def _run(args: list[str], cwd: str) -> float:
    """Run one lf-flame command in ``cwd``; its wall time (s). Raises CalledProcessError with its output."""
    t = time.perf_counter()
    subprocess.run(LF + args, check=True, capture_output=True, text=True, cwd=cwd)
    return time.perf_counter() - t


def heights(folder: str) -> pd.DataFrame:
    """Each route's per-plane heights against the truth, from ``profiles``' CSVs in ``folder``."""
    rows = []
    for route, name in PROFILES.items():
        for _, r in pd.read_csv(Path(folder) / name, keep_default_na=False).iterrows():
            rows.append(dict(route=route, depth_mm=r["depth_mm"], height_mm=r.get("height_mm", ""),
                             height_mm_true=r["height_mm_true"], height_err_mm=r.get("height_err_mm", ""),
                             flags=r.get("flags", ""), failure=r.get("failure", "")))
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, help="folder for new_user.csv and new_user.md")
    p.add_argument("--repeats", type=int, default=2, help="runs of the whole quick start, each in a new folder")
    a = p.parse_args(argv)
    if a.repeats < 1:
        p.error(f"--repeats must be >= 1. Received: {a.repeats}")
    out = Path(a.out)
    times = {i: [] for i in range(len(COMMANDS))}
    t0 = time.perf_counter()
    for rep in range(a.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            for i, cmd in enumerate(COMMANDS):
                times[i].append(_run(cmd, tmp))
                print(f"  run {rep + 1}/{a.repeats}: lf-flame {' '.join(cmd)} {times[i][-1]:.1f} s", flush=True)
            table = heights(tmp)
    wall = time.perf_counter() - t0
    timing = pd.DataFrame([dict(command="lf-flame " + " ".join(c), median_s=float(np.median(times[i])),
                                worst_s=float(np.max(times[i])), runs=len(times[i]))
                           for i, c in enumerate(COMMANDS)])
    atomic_write_text(out / "new_user.csv", table.to_csv(index=False, float_format="%.3f"))
    md = ["# A new user's quick start: each command's time and the flame heights",
          "", f"Command: `python experiments/new_user.py --out {a.out} --repeats {a.repeats}` ({wall:.0f} s). It runs "
          "the README's quick-start commands through the command line, each run of them in a new empty folder, "
          "and times each as a whole process (the interpreter's start and imports included) on this machine.", "",
          timing.to_markdown(index=False, floatfmt=".1f"), "",
          "Heights in mm against the scene's truth (the simulation's objects), from the last run's `profiles` "
          "outputs; a flagged height is one the diagnostics do not trust (`docs/diagnostics.md`).", "",
          table.to_markdown(index=False, floatfmt=".2f"), "",
          f"Provenance: `{json.dumps(provenance(), default=str)}`", ""]
    atomic_write_text(out / "new_user.md", "\n".join(md))
    print(timing.to_string(index=False))
    print(table.to_string(index=False))
    print(f"-> {out / 'new_user.csv'}, {out / 'new_user.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
