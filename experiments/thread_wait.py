"""admm's solve with Numba's OpenMP threads waiting passively (the package's setting) or spinning (libgomp's default).

After each parallel kernel libgomp's threads busy-wait (300,000 spins unless ``OMP_WAIT_POLICY`` says
otherwise) and hold the cores that SciPy's FFT threads and the next kernel want at once. ``lf_flame``
sets ``OMP_WAIT_POLICY=PASSIVE`` where the user has not set it; ``GOMP_SPINCOUNT=300000`` restores
the default's spinning in a child process (libgomp manual: a spin count given is used whatever the policy).

Each child process solves the found planes of ``make cameras``' decoded light fields (the paper's
camera, 176 x 86 lenslets, and the 48 px camera, 17 x 24; the depths its ``reconstruct`` found,
noise-free and 14 dB) by admm on the exact operator (2 x 2 grid), each light field once to warm up
(the process's first solve loads Numba's kernels from cache) and then ``--repeats`` times. Children of the
two settings alternate (A B A B ...), so a drift of the machine's speed falls on both.

Writes ``<out>/thread_wait.{csv,md,json}``. Usage: ``python experiments/thread_wait.py --out results
[--pairs 3] [--repeats 5]``; needs ``data/cameras`` (``make cameras``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from alternating import alternate  # noqa: E402

CACHE = ROOT / "data" / "cameras"
CAMERAS = ("paper", "48px")
SEEDS = (56000, 56001, 56002)
#: The two settings: the package's (passive) and libgomp's default spinning.
SETTINGS = {"passive": {}, "spin": {"GOMP_SPINCOUNT": "300000"}}


def child(repeats: int) -> None:
    """Solve every light field and print one JSON row per solve."""
    import h5py

    from lf_flame.real.readers import read_light_field
    from lf_flame.tomo.decoded import fit_data
    from lf_flame.tomo.exact import emission_operator
    from lf_flame.tomo.noise_knobs import admm_subsamples
    from lf_flame.tomo.solvers import reconstruct
    for cam in CAMERAS:
        d = CACHE / cam
        cam_file = ROOT / "data_gen" / "paper.toml" if cam == "paper" else d / "camera.toml"
        for seed in SEEDS:
            for noise in ("clean", "14dB"):
                lf = read_light_field(d / f"views{seed}_{noise}.h5", cam_file, d / "calibration.json")
                with h5py.File(d / f"rec{seed}_{noise}_admm.h5", "r") as f:
                    depths = [float(x) for x in f["depths_mm"][...]]
                for k in range(1 + repeats):
                    op = emission_operator(lf.camera, depths, subsamples=admm_subsamples(len(depths)))
                    data, fit = fit_data(lf, op)
                    rec = reconstruct(data, op, "admm", saturation=fit)
                    P, R, C = rec.planes.shape
                    print(json.dumps(dict(camera=cam, seed=seed, noise=noise, solve=k, time_s=rec.time_s,
                                          samples=P * R * C)), flush=True)


def main(argv=None) -> int:
    import pandas as pd
    from lf_flame.config import atomic_write_text, provenance
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a.repeats)
        return 0
    missing = [c for c in CAMERAS if not (CACHE / c / f"rec{SEEDS[-1]}_14dB_admm.h5").exists()]
    if missing:
        raise SystemExit(f"no decoded light fields of {missing} in {CACHE}: run `make cameras` first")
    t0 = time.perf_counter()
    reset = {k: None for k in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    rows = alternate(__file__, ["--out", a.out, "--repeats", a.repeats],
                     {name: {**reset, **extra} for name, extra in SETTINGS.items()}, a.pairs, "setting")
    df = pd.DataFrame(rows)
    df["us_per_sample_plane"] = 1e6 * df.time_s / df.samples
    warm = df[df.solve > 0]
    tab = warm.groupby(["camera", "setting"]).time_s.describe(percentiles=[0.5, 0.9])[
        ["count", "50%", "90%", "max"]].rename(columns={"50%": "median_s", "90%": "p90_s", "max": "worst_s"})
    tab["us_per_sample_plane_median"] = warm.groupby(["camera", "setting"]).us_per_sample_plane.median()
    tab = tab.reset_index()
    per = warm.groupby(["camera", "setting", "pair", "seed", "noise"]).time_s.median().unstack("setting")
    ratio = (per["spin"] / per["passive"]).groupby("camera").describe(percentiles=[0.1, 0.5])[
        ["count", "min", "10%", "50%", "max"]].reset_index()
    versus = {s: float(tab[(tab.camera == "48px") & (tab.setting == s)].us_per_sample_plane_median.iloc[0]
                       / tab[(tab.camera == "paper") & (tab.setting == s)].us_per_sample_plane_median.iloc[0])
              for s in SETTINGS}
    a.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(a.out / "thread_wait.csv", df.to_csv(index=False, float_format="%.5g"))
    cmd = f"python experiments/thread_wait.py --out {a.out}" + ("" if a.pairs == 3 else f" --pairs {a.pairs}") + \
        ("" if a.repeats == 5 else f" --repeats {a.repeats}")
    wall = time.perf_counter() - t0
    md = ["# admm's solve: OpenMP threads waiting passively or spinning", "",
          f"`{cmd}` ({wall:.0f} s on {provenance()['cpu_count']} cores). Each child process solves the found planes "
          f"of `make cameras`' decoded light fields (seeds {SEEDS[0]}-{SEEDS[-1]}, noise-free and 14 dB) by admm "
          f"(2 x 2 grid), once to warm up and {a.repeats} times timed; {a.pairs} pairs of children, the settings "
          "alternating. `passive`: `OMP_WAIT_POLICY=PASSIVE` (what `lf_flame` sets); `spin`: "
          "`GOMP_SPINCOUNT=300000` (libgomp's default busy-wait).", "",
          "Timed solves (seconds; the tail beside the median):", "",
          tab.to_markdown(index=False, floatfmt=".4g"), "",
          "Spin over passive, per light field and pair (median of its timed solves):", "",
          ratio.to_markdown(index=False, floatfmt=".3g"), "",
          "The 48 px camera's solve per sample-plane over the paper camera's (medians): " + ", ".join(
              f"{s} {v:.2f}x" for s, v in versus.items()) + ".", ""]
    atomic_write_text(a.out / "thread_wait.md", "\n".join(md))
    atomic_write_text(a.out / "thread_wait.json", json.dumps(dict(
        command=cmd, pairs=a.pairs, repeats=a.repeats, seeds=list(SEEDS), settings=SETTINGS, wall_s=wall,
        per_sample_plane_48px_over_paper=versus, provenance=provenance()), indent=1, default=float))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
