"""A new user's first light field, run as the README tells it: each route's flame heights.

Runs the commands a new user types, through the command line itself:

    lf-flame simulate --scene flame --out DIR/flame.npz
    lf-flame profiles DIR/flame.npz --route ROUTE --out DIR/prof_ROUTE      (per route)

and gathers each route's per-plane heights against the scene's truth into
``<out>/new_user.csv`` and ``<out>/new_user.md`` (with the commands, wall times and
package versions). Routes: ``shift-sum`` (refocusing) and ``reconstruct-pd-tv`` (each
plane's emission, :mod:`lf_flame.tomo`).

Usage: ``python experiments/new_user.py --out results`` (``make new-user``).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from lf_flame.config import atomic_write_text, provenance

ROUTES = ("shift-sum", "reconstruct-pd-tv")
LF = [sys.executable, "-m", "lf_flame.cli"]


def _run(args: list[str]) -> float:
    """Run one lf-flame command; its wall time (s). Raises CalledProcessError with its output."""
    t = time.perf_counter()
    subprocess.run(LF + args, check=True, capture_output=True, text=True)
    return time.perf_counter() - t


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, help="folder for new_user.csv and new_user.md")
    a = p.parse_args(argv)
    out = Path(a.out)
    rows, commands = [], []
    with tempfile.TemporaryDirectory() as tmp:
        raw = f"{tmp}/flame.npz"
        sim = ["simulate", "--scene", "flame", "--out", raw]
        commands.append(("lf-flame " + " ".join(sim).replace(tmp, "DIR"), _run(sim)))
        for route in ROUTES:
            prof = ["profiles", raw, "--route", route, "--out", f"{tmp}/prof_{route}"]
            commands.append(("lf-flame " + " ".join(prof).replace(tmp, "DIR"), _run(prof)))
            df = pd.read_csv(f"{tmp}/prof_{route}.csv", keep_default_na=False)
            for _, r in df.iterrows():
                rows.append(dict(route=route, depth_mm=r["depth_mm"], height_mm=r.get("height_mm", ""),
                                 height_mm_true=r["height_mm_true"], height_err_mm=r.get("height_err_mm", ""),
                                 flags=r.get("flags", ""), failure=r.get("failure", "")))
    table = pd.DataFrame(rows)
    atomic_write_text(out / "new_user.csv", table.to_csv(index=False, float_format="%.3f"))
    prov = provenance()
    md = ["# A new user's first light field: flame heights per route",
          "", f"Command: `python experiments/new_user.py --out {a.out}`. It runs, through the command line:", ""]
    md += [f"- `{c}` ({t:.1f} s)" for c, t in commands]
    md += ["", "Heights in mm against the scene's truth (the simulation's objects); a flagged height is one",
           "the diagnostics do not trust (`docs/diagnostics.md`).", "",
           table.to_markdown(index=False, floatfmt=".2f"), "",
           f"Provenance: `{json.dumps(prov, default=str)}`", ""]
    atomic_write_text(out / "new_user.md", "\n".join(md))
    print(table.to_string(index=False))
    print(f"-> {out / 'new_user.csv'}, {out / 'new_user.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
