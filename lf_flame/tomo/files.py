"""A reconstruction's file (HDF5) and figure (:mod:`lf_flame.tomo` recovers it).

:func:`save_reconstruction` writes the planes, their depths (mm), the grid's mm per
sample, the solver's settings and its residual per iteration, atomically;
:func:`load_reconstruction` reads them back and refuses a file that is not one;
:func:`plot_reconstruction` draws each plane beside its refocused plane and the truth
(for a volume: maximum-intensity projections and slices).
"""
from __future__ import annotations

import numpy as np

from .solvers import Reconstruction


def save_reconstruction(path, rec: Reconstruction, **attrs) -> None:
    """Write a :class:`Reconstruction` to HDF5, atomically (a temporary file, then renamed).

    Datasets ``planes`` (P, rows, cols) float32, ``depths_mm`` (P,), ``sample_mm`` (P, 2)
    (mm per grid sample: height, width), ``residuals`` (iterations,); attributes
    ``solver``, ``settings`` (JSON), ``time_s``, and ``attrs`` (JSON-encoded when not scalar).
    """
    import json
    import os
    from pathlib import Path

    import h5py
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with h5py.File(tmp, "w") as f:
        f["planes"] = rec.planes.astype(np.float32)
        f["depths_mm"] = np.asarray(rec.depths_mm, np.float64)
        f["sample_mm"] = np.asarray(rec.sample_mm, np.float64)
        f["residuals"] = np.asarray(rec.residuals, np.float64)
        f.attrs["solver"] = rec.solver
        f.attrs["settings"] = json.dumps(rec.settings)
        f.attrs["time_s"] = rec.time_s
        for k, v in attrs.items():
            f.attrs[k] = v if isinstance(v, (int, float, str)) else json.dumps(v, default=float)
    os.replace(tmp, path)


def load_reconstruction(path) -> Reconstruction:
    """Read what :func:`save_reconstruction` wrote.

    Raises
    ------
    ValueError
        A file that is not a reconstruction (a dataset or attribute missing).
    """
    import json

    import h5py
    with h5py.File(path, "r") as f:
        missing = [k for k in ("planes", "depths_mm", "sample_mm", "residuals") if k not in f]
        if missing or "solver" not in f.attrs:
            raise ValueError(f"{path} is not a reconstruction file (missing {missing or ['solver']})")
        return Reconstruction(f["planes"][...].astype(np.float64), tuple(f["depths_mm"][...]),
                              tuple(map(tuple, f["sample_mm"][...])), str(f.attrs["solver"]),
                              json.loads(f.attrs["settings"]), f["residuals"][...], float(f.attrs["time_s"]))


def plot_reconstruction(path, rec: Reconstruction, refocused=None, truth=None, title: str = "") -> None:
    """Each plane beside its refocused plane and, when known, the truth (one row per plane).

    With more than 6 planes (a volume) the figure shows instead the maximum-intensity
    projections along depth and along the columns, and the central slices.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cols = [("reconstructed", rec.planes)] + ([("refocused", refocused)] if refocused is not None else []) + \
        ([("truth", truth)] if truth is not None else [])
    vmax = max(float(np.max(c[1])) for c in cols) or 1.0
    P = len(rec.planes)
    if P <= 6:
        fig, ax = plt.subplots(P, len(cols), figsize=(2.2 * len(cols), 3.6 * P), squeeze=False)
        for k in range(P):
            for j, (name, st) in enumerate(cols):
                ax[k, j].imshow(st[k], cmap="inferno", vmin=0, vmax=vmax)
                ax[k, j].set_title(f"{name} {rec.depths_mm[k]:+.1f} mm", fontsize=8)
                ax[k, j].axis("off")
    else:
        fig, ax = plt.subplots(len(cols), 3, figsize=(9, 3.4 * len(cols)), squeeze=False)
        for j, (name, st) in enumerate(cols):
            st = np.asarray(st)
            ax[j, 0].imshow(st.max(axis=0), cmap="inferno", vmin=0)
            ax[j, 0].set_title(f"{name}: MIP along depth", fontsize=8)
            ax[j, 1].imshow(st.max(axis=2).T, cmap="inferno", aspect="auto", vmin=0,
                            extent=(rec.depths_mm[0], rec.depths_mm[-1], st.shape[1], 0))
            ax[j, 1].set_title(f"{name}: MIP along columns (depth mm →)", fontsize=8)
            ax[j, 2].imshow(st[:, :, st.shape[2] // 2].T, cmap="inferno", aspect="auto", vmin=0,
                            extent=(rec.depths_mm[0], rec.depths_mm[-1], st.shape[1], 0))
            ax[j, 2].set_title(f"{name}: central column slice", fontsize=8)
    fig.suptitle(title or f"{rec.solver}, {rec.settings.get('iters', 0)} iterations, {rec.time_s:.2f} s", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
