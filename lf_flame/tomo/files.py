"""A reconstruction's file (HDF5) and figure (:mod:`lf_flame.tomo` recovers it).

:func:`save_reconstruction` writes the planes, their depths (mm), the grid's mm per
sample, the solver's settings and its residual per iteration, atomically;
:func:`load_reconstruction` reads them back and refuses a file that is not one;
:func:`reconstruction_figure` draws each plane beside its refocused plane and the truth
(for a volume: maximum-intensity projections and slices), :func:`plot_reconstruction` writes it.
"""
from __future__ import annotations

import numpy as np

from .solvers import Reconstruction


def save_reconstruction(path, rec: Reconstruction, arrays=None, **attrs) -> None:
    """Write a :class:`Reconstruction` to HDF5, atomically (a temporary file, then renamed).

    Datasets ``planes`` (P, rows, cols) float32, ``depths_mm`` (P,), ``sample_mm`` (P, 2)
    (mm per grid sample: height, width), ``residuals`` (the solver's, :class:`~lf_flame.tomo.solvers.Reconstruction`),
    and each of ``arrays``
    (a dict of name: array, e.g. an axisymmetric flame's ``e(r, y)``) as ``extra/NAME``;
    attributes ``solver``, ``settings`` (JSON), ``time_s``, and ``attrs`` (JSON-encoded when
    not scalar).
    """
    import json
    import os
    from pathlib import Path

    import h5py
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    try:
        with h5py.File(tmp, "w") as f:
            f["planes"] = rec.planes.astype(np.float32)
            f["depths_mm"] = np.asarray(rec.depths_mm, np.float64)
            f["sample_mm"] = np.asarray(rec.sample_mm, np.float64)
            f["residuals"] = np.asarray(rec.residuals, np.float64)
            f["residuals"].attrs["meaning"] = (
                "the last solve's relative residual per iteration (admm: one per fill after the first, at the planes "
                "that fill predicts from, so the last is a step behind the planes written); the written planes' own is "
                "the misfit attribute's relative_residual, where the command records one")
            f.attrs["solver"] = rec.solver
            f.attrs["settings"] = json.dumps(rec.settings)
            f.attrs["time_s"] = rec.time_s
            for k, v in (arrays or {}).items():
                f[f"extra/{k}"] = np.asarray(v)
            for k, v in attrs.items():
                f.attrs[k] = v if isinstance(v, (int, float, str)) else json.dumps(v, default=float)
        os.replace(tmp, path)
    except BaseException:   # a full disk, Ctrl-C: no half-written file left (tomo does not import config's helper)
        tmp.unlink(missing_ok=True)
        raise


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


def load_found(path) -> list:
    """The depths a reconstruction file's route found, with their footprints and regions
    (``lf-flame reconstruct --depths auto``): ``found`` for :func:`lf_flame.tomo.scoring.score_flames`.

    Returns
    -------
    list of (depth_mm, mask, region)
        Per found depth (mm from the focus distance): the lenslets that voted for it and the region
        it was found in, boolean (R, C).

    Raises
    ------
    ValueError
        A file whose depths were given, not found (no ``found_depths``).
    """
    import json

    import h5py
    with h5py.File(path, "r") as f:
        if "found_depths" not in f.attrs:
            raise ValueError(f"{path}: its depths were given, not found (no found_depths)")
        found = json.loads(f.attrs["found_depths"])
        masks, labels = f["extra/found_masks"][...], f["extra/found_regions"][...]
    return [(r["depth_mm"], m, labels == r["region"]) for r, m in zip(found, masks)]


def _plane_extents(rec: Reconstruction) -> list:
    """Each plane's (left, right, bottom, top) in mm (x right, y up), the grid centred on the
    optical axis (:func:`lf_flame.tomo.operator.plane_grid`)."""
    out = []
    for plane, (h, w) in zip(rec.planes, rec.sample_mm):
        H, W = plane.shape[0] * h, plane.shape[1] * w
        out.append((-W / 2, W / 2, -H / 2, H / 2))
    return out


def _side_mesh(depths, sample_h, rows):
    """Vertices (rows + 1, P + 1) of a side view (depth across, y up) of planes sorted by
    depth: each plane spans half the spacing to its neighbours, and its rows span its own
    height in mm (a grid's sample height grows linearly with depth; the edges' heights
    are that line's)."""
    d = np.asarray(depths, np.float64)
    mid = (d[1:] + d[:-1]) / 2
    edges = np.concatenate([[d[0] - (mid[0] - d[0])], mid, [d[-1] + (d[-1] - mid[-1])]])
    h = np.polyval(np.polyfit(d, sample_h, 1), edges)
    r = np.arange(rows + 1)[:, None]
    return np.broadcast_to(edges, (rows + 1, len(edges))), (rows / 2 - r) * h[None, :]


def iterations_note(rec) -> str:
    """The iterations that ran: admm's fills (``settings["fills_run"]``, "of at most" the cap where
    they converged sooner), else the solver's ``settings["iters"]``."""
    cap = int(rec.settings.get("iters", 0))
    if rec.solver == "learned":
        return f"the network of {rec.settings.get('model')}"
    if rec.solver != "admm":
        return f"{cap} iterations"
    ran = int(rec.settings.get("fills_run", cap))
    return f"{ran} fills" + (f" of at most {cap}, converged" if ran < cap else "")


def plot_reconstruction(path, rec: Reconstruction, refocused=None, truth=None, title: str = "",
                        truth_depths_mm=None) -> None:
    """Write :func:`reconstruction_figure` to ``path`` (PNG), atomically."""
    from ..measure.figures import save_figure
    save_figure(reconstruction_figure(rec, refocused, truth, title, truth_depths_mm), path, dpi=110)


def reconstruction_figure(rec: Reconstruction, refocused=None, truth=None, title: str = "", truth_depths_mm=None):
    """Each plane beside its refocused plane and, when known, the truth (one row per plane).

    Every panel is in object-space mm (x right, y up; each plane on its own grid, centred on
    the optical axis). Reconstructed and true emission share one colour scale from 0; the
    refocused planes, which carry the light of every plane (defocused), have their own
    (a colour bar each, the scene's radiance units). With more than 6 planes (a volume)
    the figure shows instead, per column: the maximum over depth (each plane's grid, as
    the camera sees it: lenslets), a side view (maximum over x) and a slice at one x (mm)
    through the brightest column (summed over rows) of the truth, else of the
    reconstruction, depth across: each plane is drawn over half the spacing to its
    neighbours, at its own height in mm; and the depth profile (each plane's sum).

    Parameters
    ----------
    rec : Reconstruction
    refocused, truth : ndarray of shape (P, rows, cols) or None
        The planes refocused at the same depths on the same grid, and the true emission
        (:func:`lf_flame.tomo.truth.scene_truth`).
    title : str
        The figure's title (default: the solver, its iterations and time).
    truth_depths_mm : sequence of P float or None
        The true depth (mm) of what each truth plane holds (:func:`lf_flame.tomo.truth.truth_depths`),
        which titles the truth's panels; None (or NaN): the plane's depth. Depths are written
        with their sign and never as ``-0.0`` (:func:`lf_flame.measure.figures.signed`).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..measure.figures import add_colorbar, panel_grid, show_plane, signed
    cols = [("reconstructed", np.asarray(rec.planes))]
    cols += [("refocused", np.asarray(refocused))] if refocused is not None else []
    cols += [("truth", np.asarray(truth))] if truth is not None else []
    # emission (reconstructed, truth) on one scale; refocused planes, which carry the light of
    # a whole slab (of every plane, defocused), on their own
    emission = [st for name, st in cols if name != "refocused"]
    scales = {"emission": max(float(np.max(st)) for st in emission) or 1.0}
    if refocused is not None:
        scales["refocused"] = float(np.max(refocused)) or 1.0

    def style(name):
        return dict(cmap="inferno", vmin=0, vmax=scales["refocused" if name == "refocused" else "emission"])
    images = {}
    P = len(rec.planes)
    title = title or f"{rec.solver}, {iterations_note(rec)}, {rec.time_s:.2f} s"
    if P <= 6:
        ext = _plane_extents(rec)
        aspect = max((e[3] - e[2]) / (e[1] - e[0]) for e in ext)
        fig, ax, bars = panel_grid(P, len(cols), aspect, colorbars=1 + (refocused is not None), suptitle=title)
        caxes = dict(zip(["reconstructed", "refocused"], bars))
        true_d = np.full(P, np.nan) if truth_depths_mm is None else np.asarray(truth_depths_mm, np.float64)
        for k in range(P):
            for j, (name, st) in enumerate(cols):
                d = true_d[k] if name == "truth" and np.isfinite(true_d[k]) else rec.depths_mm[k]
                images[name] = show_plane(ax[k, j], st[k], ext[k], title=f"{name} {signed(d)} mm", ylabel=j == 0,
                                          **style(name))
    else:
        order = np.argsort(rec.depths_mm)
        depths = np.asarray(rec.depths_mm, np.float64)[order]
        sample = np.asarray(rec.sample_mm, np.float64)[order]
        rows, ncol = rec.planes.shape[1:]
        X, Y = _side_mesh(depths, sample[:, 0], rows)
        ref = cols[-1][1][order] if truth is not None else np.asarray(rec.planes)[order]
        k0, c0 = np.unravel_index(int(np.argmax(ref.sum(axis=1))), (len(ref), ncol))   # the brightest column
        x0 = (c0 + 0.5 - ncol / 2) * sample[k0, 1]
        # column coordinate of x0 on each plane's grid: linear interpolation between columns
        cpos = x0 / sample[:, 1] + ncol / 2 - 0.5
        lo = np.clip(np.floor(cpos).astype(int), 0, ncol - 1)
        hi = np.clip(lo + 1, 0, ncol - 1)
        f = np.clip(cpos - lo, 0.0, 1.0)
        inside = (cpos >= -0.5) & (cpos <= ncol - 0.5)
        top_view = float(np.clip(rows / ncol, 0.4, 2.0))                  # the max over depth: lenslets
        fig, ax, bars = panel_grid(len(cols), 4, 1.1, colorbars=1 + (refocused is not None), suptitle=title,
                                   widths_in=[float(np.clip(2.64 / top_view, 1.3, 4.0)), 3.0, 3.0, 3.0])
        caxes = dict(zip(["reconstructed", "refocused"], bars))
        for j, (name, st) in enumerate(cols):
            st = st[order]
            images[name] = ax[j, 0].imshow(st.max(axis=0), **style(name))
            ax[j, 0].set_title(f"{name}: max over depth", fontsize=8)
            ax[j, 0].set_xlabel("column (lenslet)", fontsize=7)
            ax[j, 0].set_ylabel("row (lenslet)", fontsize=7)
            ax[j, 1].pcolormesh(X, Y, st.max(axis=2).T, shading="flat", **style(name))
            ax[j, 1].set_title(f"{name}: max over x", fontsize=8)
            kk = np.arange(len(st))
            sl = (st[kk, :, lo[kk]] * (1 - f)[:, None] + st[kk, :, hi[kk]] * f[:, None]) * inside[:, None]
            ax[j, 2].pcolormesh(X, Y, sl.T, shading="flat", **style(name))
            ax[j, 2].set_title(f"{name}: slice at x = {x0:+.2f} mm", fontsize=8)
            sums = st.sum(axis=(1, 2))
            ax[j, 3].plot(depths, sums, ".-", ms=3)
            ax[j, 3].set_title(f"{name}: summed over each plane", fontsize=8)
            ax[j, 3].set_ylabel("sum (radiance units x samples)", fontsize=7)
            # headroom above the largest: refocused planes each hold all the light, a flat line on the top edge
            ax[j, 3].set_ylim(0, 1.1 * float(sums.max()) if sums.max() > 0 else 1.0)
            for a in ax[j, 1:]:
                a.set_xlabel("depth (mm from the focal plane)", fontsize=7)
            for a in ax[j, 1:3]:
                a.set_ylabel("y (mm)", fontsize=7)
            for a in ax[j]:
                a.tick_params(labelsize=6)
    for name, label in (("reconstructed", "emission (the scene's radiance units)"),
                        ("refocused", "refocused (the scene's radiance units)")):
        if name in images:
            add_colorbar(fig, images[name], ax, label, cax=caxes[name])
    return fig
