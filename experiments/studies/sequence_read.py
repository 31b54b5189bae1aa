"""Reading an HDF5 recording: one open of the file per frame (the earlier reading) against one
open per chunk (:meth:`lf_flame.recordings.sources.H5Source.frames`), on the same frames,
interleaved, repeated; and what the opens alone cost (open and close, nothing read).
Writes ``results/sequence_read.csv`` (one row per pass).

    python experiments/studies/sequence_read.py --h5 data/sequence/speed.h5 --out results

The file is the speed stage's (``experiments/sequence.py``: 320 frames, uint16, lzf).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text
from lf_flame.recordings.job import CHUNK
from lf_flame.recordings.sources import open_source


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--h5", required=True)
    p.add_argument("--out", default="results")
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args(argv)
    src, _ = open_source(a.h5)
    n = src.n_frames
    rows = []
    for rep in range(a.repeats):
        for mode in ("one open per frame", "one open per chunk", "opens alone, one per frame"):
            t = time.perf_counter()
            if mode.startswith("opens alone"):
                import h5py
                for _ in range(n):
                    with h5py.File(src.path, "r"):
                        pass
            for c in range(0, n, CHUNK) if not mode.startswith("opens alone") else ():
                if mode == "one open per frame":
                    frames = [src.raw(i) for i in range(c, min(c + CHUNK, n))]
                else:
                    frames = list(src.frames(c, min(c + CHUNK, n)))
                assert len(frames) == min(CHUNK, n - c)
            dt = time.perf_counter() - t
            rows.append(dict(mode=mode, repeat=rep, n_frames=n, chunk=CHUNK, read_ms_per_frame=1e3 * dt / n))
            print(rows[-1], flush=True)
    d = pd.DataFrame(rows)
    out = Path(a.out)
    atomic_write_text(out / "sequence_read.csv", d.to_csv(index=False, float_format="%.6g"))
    g = d.groupby("mode").read_ms_per_frame
    per_frame = d[d["mode"] == "one open per frame"].read_ms_per_frame.to_numpy()
    per_chunk = d[d["mode"] == "one open per chunk"].read_ms_per_frame.to_numpy()
    print(g.describe().to_string())
    print(f"ratio per frame / per chunk, pass by pass: {', '.join(f'{v:.2f}' for v in per_frame / per_chunk)}; "
          f"median {np.median(per_frame / per_chunk):.2f}  ({' '.join(sys.argv)})")


if __name__ == "__main__":
    main()
