"""The temperature guide's colour recording, run as the guide gives it: each command's time, the depths found and how
each plane's temperature follows its flame's sheath.

In one empty folder, with ``examples/paper_camera.toml`` and ``cfa = "RGGB"`` added to its ``[sensor]``
(docs/guide/temperature.md, "a colour recording to try it on"):

    lf-flame simulate --camera cam.toml --scene furnace --temperature T --out bbT.npz      (T = 1600, 2000, 2400)
    lf-flame calibrate-temperature bb1600.npz bb2000.npz bb2400.npz --temperature ... --out bb.json
    lf-flame simulate-sequence --camera cam.toml --colour --fps 100 --duration 0.1 --rays-per-pixel 16 --out crec.h5
    lf-flame temperature crec.h5 --calibration bb.json --route admm-cfa --out T.h5

Each command is timed as a whole process. Per plane ``temperature`` found (``T.csv``), against the flame at the
nearest true depth: the depth error, the correlation over the frames of the plane's median temperature with the
flame's sheath temperature (``sheath_temperature_k`` of the recording, the truth), and how far the median lies below
the sheath (the sheath is the flame's hottest layer). Writes ``<out>/guide_temperature.{md,csv}``.

Usage: ``python experiments/guide_temperature.py --out results`` (``make guide-temperature``; about 2 min on 2 cores).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text, provenance

ROOT = Path(__file__).resolve().parents[1]
FURNACE_K = (1600, 2000, 2400)
COMMANDS = (
    *(["simulate", "--camera", "cam.toml", "--scene", "furnace", "--temperature", str(t), "--out", f"bb{t}.npz"]
      for t in FURNACE_K),
    ["calibrate-temperature", *(f"bb{t}.npz" for t in FURNACE_K),
     *(a for t in FURNACE_K for a in ("--temperature", str(t))), "--out", "bb.json"],
    ["simulate-sequence", "--camera", "cam.toml", "--colour", "--fps", "100", "--duration", "0.1",
     "--rays-per-pixel", "16", "--out", "crec.h5"],
    ["temperature", "crec.h5", "--calibration", "bb.json", "--route", "admm-cfa", "--out", "T.h5"],
)


def colour_camera(work: Path) -> Path:
    """``examples/paper_camera.toml`` with ``cfa = "RGGB"`` in its ``[sensor]``, as the guide says."""
    text = (ROOT / "examples" / "paper_camera.toml").read_text()
    assert "\n[sensor]\n" in text
    path = work / "cam.toml"
    path.write_text(text.replace("\n[sensor]\n", '\n[sensor]\ncfa = "RGGB"\n'))
    return path


def plane_rows(work: Path) -> pd.DataFrame:
    """Per plane found: its depth against the nearest flame's, the correlation of its median temperature over the
    frames with that flame's sheath temperature, and the mean of sheath less median (K)."""
    with h5py.File(work / "crec.h5") as f:
        sheath = f["sheath_temperature_k"][...]                         # (frames, flames), farthest flame first
        flames = json.loads(f.attrs["sequence"])["flames"]
    true = np.array([float(fl["depth_offset_mm"]) for fl in flames])
    rows = []
    for k, g in pd.read_csv(work / "T.csv").groupby("plane"):
        g = g.sort_values("frame")
        d = float(g.depth_mm.iloc[0])
        j = int(np.argmin(np.abs(true - d)))
        rows.append(dict(plane=int(k), depth_mm=d, depth_mm_true=true[j], depth_err_mm=d - true[j],
                         frames=len(g), median_k=float(g.median_k.median()),
                         correlation=float(np.corrcoef(g.median_k, sheath[:, j])[0, 1]),
                         sheath_less_median_k=float(np.mean(sheath[:, j] - g.median_k.to_numpy()))))
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        colour_camera(work)
        for cmd in COMMANDS:
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "lf_flame.cli", *cmd], check=True, capture_output=True, cwd=work)
            times.append(dict(command="lf-flame " + " ".join(cmd), wall_s=time.perf_counter() - t))
            print(f"{times[-1]['wall_s']:6.1f} s  {times[-1]['command']}", flush=True)
        df = plane_rows(work)
    wall = time.perf_counter() - t_all
    atomic_write_text(a.out / "guide_temperature.csv", df.to_csv(index=False, float_format="%.6g"))
    fmt = dict(index=False, floatfmt=".4g")
    md = ["# The temperature guide's colour recording", "",
          f"`python experiments/guide_temperature.py --out {a.out}` ({wall:.0f} s; `make guide-temperature`): the "
          "commands of docs/guide/temperature.md ('a colour recording to try it on') with examples/paper_camera.toml "
          "and `cfa = \"RGGB\"` added to its [sensor], each a whole process in one empty folder on this machine (2 "
          "cores).", "", pd.DataFrame(times).to_markdown(**fmt), "",
          "Per plane found: depth against the nearest flame's; `correlation` of the plane's median temperature over "
          "the frames with that flame's sheath temperature (the recording's truth, flickering +- 40 K); "
          "`sheath_less_median_k`: the mean of sheath less median (the sheath is the flame's hottest layer).", "",
          df.to_markdown(**fmt), "",
          f"Provenance: `{json.dumps(provenance(), default=str)}`", ""]
    atomic_write_text(a.out / "guide_temperature.md", "\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
