"""The camera's depth-resolution map: how close two planes may lie and still be told apart.

The physics. Flames are optically thin, so the views are a linear function of the emission
``x_k`` on ``P`` planes; per view ``v`` and plane ``k`` that map is a 2-D convolution over
lenslets with a small kernel ``h_vk`` (:mod:`lf_flame.tomo.exact`). In the Fourier domain
over lenslets every lateral frequency ``f`` (cycles per lenslet, which is cycles per sample
of every plane's grid) is on its own:

    ``Y_v(f) = sum_k H_vk(f) X_k(f)``,   ``G(f) = sum_v conj(H_v(f)) H_v(f)^T`` (``P x P``),

``H_v(f)`` the view's kernel response per plane and ``G(f)`` the normal matrix of the
least-squares problem at that frequency. The planes' content at ``f`` is recovered from
the data alone as well as ``G(f)`` is conditioned: along the eigenvector of its smallest
eigenvalue, white noise of the views is amplified ``lambda_max / lambda_min`` times more (in
variance) than along the best-determined one. What separates two planes is parallax: view
``v`` sees plane ``k`` shifted by its slope times the view's offset, so at frequency ``f``
the two planes' responses differ in phase across the views by ``2 pi f (s_i - s_j) u``;
over the aperture's ``N`` views this decorrelates once ``f |s_i - s_j| N`` is of order one.
The slope is affine in depth near focus, so the smallest separable spacing grows in
proportion to ``1 / f``: to the feature size. At ``f = 0`` every plane gives every view
the same light: a feature as large as a whole flame is not depth-resolved by the data.

The map (:func:`depth_resolution`). For a dense stack (default 81 planes every 0.5 mm from
-15 to +25 mm) and a feature of size ``s`` mm (half a period, so ``1 / (2 s)`` cycles per
mm; on plane ``k`` of sample ``a_k`` mm that is ``f_k = a_k / (2 s)`` cycles per sample):

- *smallest resolvable spacing at condition c*: for every pair of planes ``(i, j)`` of the
  stack, the condition number of the 2 x 2 block ``G(f)[[i, j]][:, [i, j]]`` at the pair's
  frequency ``f = (a_i + a_j) / (4 s)`` (the feature seen at the pair's mean sample; the
  sample grows about 12 % over 40 mm on the paper's camera). For each spacing
  ``j - i`` the pairs at every position across the stack are summarised by their **median**
  and their **worst** (largest) condition number; the smallest resolvable spacing is the
  smallest spacing whose summary is ``<= c`` (``inf`` when none within the stack is). The
  condition falls as the spacing grows (as ``1 / spacing^2`` at first) down to near 1;
  the crossing is also interpolated between the stack's spacings (log-log), finer than
  the stack's grid. The condition also carries the two planes' different throughput at
  ``f``: far from focus a pixel's footprint spans several samples and blurs a fine
  feature out (on the paper's camera a 0.2 mm feature keeps 0.5 % of its best plane's
  energy at +25 mm, 11 % at -15 mm), so near the sampling limit it rises again at large
  spacings: the far plane is then barely seen rather than confused with the near one.
  The smallest spacing is the first crossing;
- *independent depth modes*: the eigenvalues of the whole stack's ``G(f)`` above
  ``lambda_max / c``, at the frequency of the stack's mean sample, ``f = mean(a) / (2 s)``.

The frequency lies along the lenslet rows (``axis="rows"``, the default: ``f`` along ``y``,
0 along ``x``), along the columns, or along the diagonal (``f / sqrt 2`` on each axis). A
feature finer than the coarsest plane's sample (``f > 0.5`` cycles per sample on some
plane: above the grids' Nyquist frequency) is not mapped (NaN).

Simplifications, all optimistic for what the data alone can tell: an unbounded field (no
border, where fewer views see a plane), the per-pixel cos^4 drift left out (the kernels'
aperture and cos^4 at the field centre are in, :func:`~lf_flame.tomo.quadrature.exact_kernels`),
equal white noise on every pixel, no saturation, and no prior: non-negativity, the
planes' support and smoothness make a solver do better than this map says, which is why
the paper's four flames 10 mm apart reconstruct although whole flames are not resolved.

Source: the normal-equation (Fourier) analysis of limited-angle tomography and light-field
depth resolution, e.g. Levoy et al., "Light field microscopy", SIGGRAPH 2006 (the
depth-of-field and resolution trade-off), and Broxton et al., Opt. Express 21 (2013) 25418
(the light-field microscope's wave-optics point-spread function and its resolution);
kernels from the project's tracer (``lf_flame.tomo.exact``).
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from typing import TYPE_CHECKING

import numpy as np

from ..optics.camera import PAPER_CAMERA, PlenopticCamera
from ..simulate.scenes import FLAME_EFFECTS
from ..simulate.layers import Effects

from .conditioning import _sample_mm, normal_matrix, pair_conditions

if TYPE_CHECKING:
    from .quadrature import ExactKernels

# The module imports only NumPy and the camera at the top (its constants are the command
# line's defaults); :func:`depth_resolution` imports the quadrature (Numba, SciPy, PyLops).

#: The dense stack: every 0.5 mm from -15 to +25 mm (81 planes).
DEFAULT_NEAR_MM, DEFAULT_FAR_MM, DEFAULT_SPACING_MM = -15.0, 25.0, 0.5
#: Feature sizes (half a period, mm) of the table: from about 2.5 samples of the paper's
#: camera (0.13 mm) up to a whole flame's width.
FEATURE_SIZES_MM = (0.33, 0.66, 1.3, 2.6, 6.6)
#: Condition numbers of the table: 10 (noise amplified at most 10 x in variance between
#: the best- and worst-determined combination of the two planes) and 100.
CONDITIONS = (10.0, 100.0)
#: Directions of the lateral frequency.
AXES = ("rows", "columns", "diagonal")
#: Most planes a stack may have (the pairs grow as P^2).
MAX_PLANES = 401


def _round(x: float, digits: int = 2) -> float:
    """``x`` to ``digits`` significant digits."""
    return float(f"{x:.{digits}g}")


def camera_stack(camera: PlenopticCamera) -> tuple:
    """The default stack and feature sizes of ``camera``'s map: the paper camera's carried to it.

    The stack :data:`DEFAULT_NEAR_MM` to :data:`DEFAULT_FAR_MM` is taken in the paper camera's parallax across
    the aperture (:func:`lf_flame.tomo.depth.depth_scale`, the depth finder's scaling), clipped to what the
    camera refocuses (:func:`lf_flame.optics.depth_range.imaging_range_mm`), in 80 steps; the feature sizes
    :data:`FEATURE_SIZES_MM` in lenslet footprints at the focal plane. Each is rounded to two significant
    digits, so the paper's camera gets its own values.

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid (a real grid's decoded views' camera).

    Returns
    -------
    near_mm, far_mm, spacing_mm : float
        mm from the focal plane, > 0 farther.
    feature_mm : tuple of float
        Half a period, mm.
    """
    from ..measure.diagnostics import lenslet_size_mm
    from ..optics.depth_range import imaging_range_mm
    from .depth import depth_scale
    scale = depth_scale(camera, camera.pixels_per_lenslet)
    lo, hi = imaging_range_mm(camera)
    near, far = _round(max(DEFAULT_NEAR_MM * scale, lo)), _round(min(DEFAULT_FAR_MM * scale, hi))
    near, far = max(near, lo), min(far, hi)             # rounding past the range's ends
    ratio = lenslet_size_mm(camera, 0.0) / lenslet_size_mm(PAPER_CAMERA, 0.0)     # mm per lenslet at focus
    return near, far, _round((far - near) / 80), tuple(_round(f * ratio) for f in FEATURE_SIZES_MM)


def stack_depths(near_mm: float = DEFAULT_NEAR_MM, far_mm: float = DEFAULT_FAR_MM,
                 spacing_mm: float = DEFAULT_SPACING_MM) -> np.ndarray:
    """Depths (mm from the focal plane, > 0 farther) of a stack every ``spacing_mm`` from
    ``near_mm`` to ``far_mm``.

    Returns
    -------
    depths : ndarray of shape (P,), float64
        ``near_mm + spacing_mm * arange(P)``, the last plane at or just below ``far_mm``.

    Raises
    ------
    ValueError
        Non-finite values, ``spacing_mm <= 0``, ``near_mm >= far_mm``, or more than
        :data:`MAX_PLANES` planes.
    """
    near, far, step = float(near_mm), float(far_mm), float(spacing_mm)
    if not all(math.isfinite(v) for v in (near, far, step)):
        raise ValueError(f"near, far and spacing must be finite. Received: {near_mm!r}, {far_mm!r}, {spacing_mm!r}")
    if step <= 0:
        raise ValueError(f"the plane spacing must be > 0 mm. Received: spacing={spacing_mm!r}")
    if near >= far:
        raise ValueError(f"the near end must lie in front of the far end (near < far). Received: near={near_mm!r}, "
                         f"far={far_mm!r}")
    P = int(math.floor((far - near) / step + 1e-9)) + 1
    if P > MAX_PLANES:
        raise ValueError(f"{P} planes from {near:g} to {far:g} mm every {step:g} mm: at most {MAX_PLANES}; "
                         "give a larger spacing")
    return near + step * np.arange(P)


@dataclasses.dataclass(frozen=True)
class DepthResolution:
    """The depth-resolution map of one camera and stack (:func:`depth_resolution`).

    Attributes
    ----------
    feature_mm : ndarray of shape (F,)
        Feature sizes, half a period, mm.
    conditions : tuple of float, length C
    spacing_median_mm, spacing_worst_mm : ndarray of shape (F, C)
        Smallest resolvable plane spacing (mm) with the median / the worst condition number
        over the pairs' positions across the stack at or below each condition; ``inf``: not
        within the stack; NaN: the feature is finer than the planes' sample.
    spacing_interp_mm : ndarray of shape (F, C)
        The median's crossing of each condition interpolated between the stack's spacings
        (log-log; not below the stack's spacing).
    modes : ndarray of shape (F, C), float64
        Independent depth modes of the stack: eigenvalues of ``G(f)`` above
        ``lambda_max / c`` (NaN where not mapped).
    spacings_mm : ndarray of shape (P - 1,)
        The pair spacings, ``s * spacing``.
    cond_median, cond_worst : ndarray of shape (F, P - 1)
        The pairs' condition numbers against spacing (median, worst over positions).
    depths_mm : ndarray of shape (P,)
    sample_mm : ndarray of shape (P,)
        Each plane's sample (mm) along ``axis``.
    axis : str
    camera : PlenopticCamera or None
    setup_s, map_s : float
        Wall time of the kernels' quadrature and of the map, seconds.
    """

    feature_mm: np.ndarray
    conditions: tuple
    spacing_median_mm: np.ndarray
    spacing_worst_mm: np.ndarray
    spacing_interp_mm: np.ndarray
    modes: np.ndarray
    spacings_mm: np.ndarray
    cond_median: np.ndarray
    cond_worst: np.ndarray
    depths_mm: np.ndarray
    sample_mm: np.ndarray
    axis: str
    camera: PlenopticCamera
    setup_s: float
    map_s: float

    def to_frame(self):
        """The table: one row per feature size, columns ``feature_mm``, ``f_cycles_per_lenslet``
        (at the stack's mean sample) and per condition ``c``: ``spacing_median_mm_c``,
        ``spacing_worst_mm_c``, ``spacing_interp_mm_c``, ``modes_c``, ``spacing_over_feature_c``
        (interpolated over feature size). A pandas DataFrame."""
        import pandas as pd
        d = {"feature_mm": self.feature_mm,
             "f_cycles_per_lenslet": float(np.mean(self.sample_mm)) / (2.0 * self.feature_mm)}
        for ci, c in enumerate(self.conditions):
            tag = f"{c:g}"
            d[f"spacing_median_mm_{tag}"] = self.spacing_median_mm[:, ci]
            d[f"spacing_worst_mm_{tag}"] = self.spacing_worst_mm[:, ci]
            d[f"spacing_interp_mm_{tag}"] = self.spacing_interp_mm[:, ci]
            d[f"modes_{tag}"] = self.modes[:, ci]
            d[f"spacing_over_feature_{tag}"] = self.spacing_interp_mm[:, ci] / self.feature_mm
        return pd.DataFrame(d)

    def markdown(self) -> str:
        """The table in Markdown: per feature size and condition number, the smallest spacing
        on the stack's grid (median over positions, worst in brackets, then the median's
        interpolated crossing; ``<= s`` where the stack's spacing ``s`` already resolves it)
        and the depth modes."""
        span = float(self.depths_mm[-1] - self.depths_mm[0])

        first = float(self.spacings_mm[0])

        def mm(v):
            if np.isnan(v):
                return "finer than a sample"
            if np.isinf(v):
                return f"> {span:g}"
            return f"<= {v:g}" if abs(v - first) < 1e-9 else f"{v:.3g}"
        head = ["feature size (half a period), mm"]
        head += [f"smallest spacing, cond <= {c:g}: median (worst); interpolated, mm" for c in self.conditions]
        head += [f"depth modes in {span:g} mm, cond <= {c:g}" for c in self.conditions]
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for fi, s in enumerate(self.feature_mm):
            row = [f"{s:g}"]
            row += [f"{mm(self.spacing_median_mm[fi, ci])} ({mm(self.spacing_worst_mm[fi, ci])}); "
                    f"{mm(self.spacing_interp_mm[fi, ci])}" for ci in range(len(self.conditions))]
            row += ["–" if np.isnan(m) else f"{int(m)}" for m in self.modes[fi]]
            lines.append("| " + " | ".join(row) + " |")
        note = self.unmapped_modes_note()
        return "\n".join(lines) + "\n" + (f"\n{note}\n" if note else "")

    def unmapped_modes_note(self) -> str | None:
        """What a "–" in the depth modes' columns means where the row's spacings are mapped, or None where no row
        has one: the modes are counted on the whole stack at its mean sample, which such a feature is finer than,
        while its spacings come from the pairs of planes whose own sample holds it (the nearer, finer-sampled
        planes of a stack whose sample grows with depth: a camera's 1.5 mm feature over -289 .. +1973 mm had
        printed its spacings beside "–" with no word of why)."""
        sizes, planes = [], []
        for fi, s in enumerate(self.feature_mm):
            if not (np.all(np.isnan(self.modes[fi])) and not np.all(np.isnan(self.spacing_median_mm[fi]))):
                continue
            held = self.depths_mm[self.sample_mm <= s]
            sizes.append(f"{s:g}")
            planes.append(f"{s:g} mm: the planes at {held.min():+.4g} to {held.max():+.4g} mm")
        if not sizes:
            return None
        return (f"–: depth modes not mapped. They are counted on the whole stack at its mean sample "
                f"({float(np.mean(self.sample_mm)):.3g} mm along the {self.axis}), and features of {', '.join(sizes)} "
                "mm are finer than that (half a period under one sample, past the planes' grid); their spacings come "
                f"from the pairs of planes whose own sample holds them ({'; '.join(planes)})")


def _smallest(spacings, cond, c) -> float:
    """Smallest spacing whose condition number is <= c (inf: none; NaN: not mapped)."""
    if np.all(np.isnan(cond)):
        return float("nan")
    ok = np.flatnonzero(cond <= c)
    return float(spacings[ok[0]]) if ok.size else float("inf")


def _crossing(spacings, cond, c) -> float:
    """The spacing where the condition number crosses ``c``, interpolated linearly in log
    spacing and log condition between the grid's spacings that bracket it (the condition
    falls as 1 / spacing^2 at small spacings); the stack's spacing when its first pair is
    already <= c; inf and NaN as :func:`_smallest`."""
    if np.all(np.isnan(cond)):
        return float("nan")
    ok = np.flatnonzero(cond <= c)
    if not ok.size:
        return float("inf")
    i = ok[0]
    if i == 0 or not np.isfinite(cond[i - 1]):
        return float(spacings[i])
    t = (math.log(cond[i - 1]) - math.log(c)) / (math.log(cond[i - 1]) - math.log(max(cond[i], 1e-300)))
    return float(math.exp(math.log(spacings[i - 1]) + t * (math.log(spacings[i]) - math.log(spacings[i - 1]))))


def resolution_from_kernels(kern: ExactKernels, feature_mm=FEATURE_SIZES_MM, conditions=CONDITIONS,
                            axis: str = "rows", camera: PlenopticCamera | None = None) -> DepthResolution:
    """The map from a stack's kernels (:func:`depth_resolution` without the quadrature; one
    set of kernels serves several axes and feature sets).

    Parameters
    ----------
    kern : ExactKernels
        Of at least 2 evenly spaced planes in increasing depth
        (:func:`~lf_flame.tomo.quadrature.exact_kernels` of :func:`stack_depths`).
    feature_mm, conditions, axis
        As :func:`depth_resolution`.
    camera : PlenopticCamera or None
        The kernels' camera, recorded in the result (None: left as None).

    Returns
    -------
    DepthResolution
        Its ``setup_s`` is 0.

    Raises
    ------
    ValueError
        Fewer than 2 planes, planes not evenly spaced in increasing depth, an unknown axis,
        a feature size or condition number that is not a positive finite number (condition
        numbers must be >= 1).
    """
    t0 = time.perf_counter()
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}. Received: {axis!r}")
    depths = np.asarray(kern.depths_mm, np.float64)
    steps = np.diff(depths)
    if depths.size < 2 or not np.all(steps > 0) or np.ptp(steps) > 1e-6 * steps[0]:
        raise ValueError("the map needs at least 2 planes, evenly spaced in increasing depth. "
                         f"Received depths {depths.tolist()}")
    feats = np.atleast_1d(np.asarray(feature_mm, np.float64))
    if feats.size == 0 or not np.all(np.isfinite(feats) & (feats > 0)):
        raise ValueError(f"feature sizes must be positive finite mm. Received: {feature_mm!r}")
    conds = tuple(float(c) for c in np.atleast_1d(conditions))
    if not conds or not all(math.isfinite(c) and c >= 1 for c in conds):
        raise ValueError(f"condition numbers must be finite and >= 1. Received: {conditions!r}")
    P = depths.size
    sample = _sample_mm(kern, axis)
    spacings = steps[0] * np.arange(1, P)
    cmed = np.full((feats.size, P - 1), np.nan)
    cworst = np.full((feats.size, P - 1), np.nan)
    sp_med = np.full((feats.size, len(conds)), np.nan)
    sp_worst = np.full((feats.size, len(conds)), np.nan)
    sp_interp = np.full((feats.size, len(conds)), np.nan)
    modes = np.full((feats.size, len(conds)), np.nan)
    for fi, s in enumerate(feats):
        pc = pair_conditions(kern, s, axis)
        if np.all(np.isnan(pc)):
            continue                                  # finer than the planes' sample
        some = ~np.all(np.isnan(pc), axis=1)          # spacings with a pair mapped
        cmed[fi, some] = np.nanmedian(pc[some], axis=1)
        cworst[fi, some] = np.nanmax(pc[some], axis=1)
        f = float(np.mean(sample)) / (2.0 * s)
        ev = np.linalg.eigvalsh(normal_matrix(kern, f, axis))
        for ci, c in enumerate(conds):
            sp_med[fi, ci] = _smallest(spacings, cmed[fi], c)
            sp_worst[fi, ci] = _smallest(spacings, cworst[fi], c)
            sp_interp[fi, ci] = _crossing(spacings, cmed[fi], c)
            modes[fi, ci] = float(np.sum(ev > ev[-1] / c)) if f <= 0.5 else np.nan
    return DepthResolution(
        feature_mm=feats, conditions=conds, spacing_median_mm=sp_med, spacing_worst_mm=sp_worst,
        spacing_interp_mm=sp_interp, modes=modes, spacings_mm=spacings, cond_median=cmed, cond_worst=cworst,
        depths_mm=depths, sample_mm=sample, axis=axis, camera=camera, setup_s=0.0, map_s=time.perf_counter() - t0)


def stack_settings(camera: PlenopticCamera, near_mm: float | None = None, far_mm: float | None = None,
                   spacing_mm: float | None = None, feature_mm=None) -> tuple:
    """The stack and feature sizes of ``camera``'s map: those given, the camera's (:func:`camera_stack`) for each
    left None: ``(near_mm, far_mm, spacing_mm, feature_mm)`` as :func:`camera_stack` returns them."""
    given = (near_mm, far_mm, spacing_mm, feature_mm)
    if None not in given:
        return near_mm, far_mm, spacing_mm, tuple(feature_mm)
    own = camera_stack(camera)
    return tuple(own[k] if v is None else v for k, v in enumerate(given[:3])) + (
        tuple(own[3] if feature_mm is None else feature_mm),)


def depth_resolution(camera: PlenopticCamera | None = None, *, near_mm: float | None = None,
                     far_mm: float | None = None, spacing_mm: float | None = None,
                     feature_mm=None, conditions=CONDITIONS, axis: str = "rows",
                     effects: Effects = FLAME_EFFECTS, quadrature_nodes: int | None = None) -> DepthResolution:
    """The camera's depth-resolution map over a dense stack (module docstring).

    Parameters
    ----------
    camera : PlenopticCamera or None
        A perfect lenslet grid (:func:`~lf_flame.tomo.quadrature.exact_kernels`); None: the
        paper's camera.
    near_mm, far_mm, spacing_mm : float or None
        The stack (:func:`stack_depths`), mm from the focal plane, > 0 farther; None: the camera's
        (:func:`camera_stack`: on the paper's camera every 0.5 mm from -15 to +25 mm).
    feature_mm : sequence of float or None
        Feature sizes, half a period, mm; None: the camera's (:func:`camera_stack`).
    conditions : sequence of float
        Condition numbers (>= 1).
    axis : {"rows", "columns", "diagonal"}
        Direction of the lateral frequency.
    effects : Effects
        Aperture and cos^4 of the kernels (occlusion and crosstalk off).
    quadrature_nodes : int or None
        Of the kernels' quadrature; None: :data:`lf_flame.tomo.quadrature.QUADRATURE_NODES`.

    Returns
    -------
    DepthResolution

    Raises
    ------
    ValueError
        A bad stack (:func:`stack_depths`), feature size, condition or axis, or a camera the
        exact kernels cannot be built for (not a perfect grid, a plane it cannot image).

    Notes
    -----
    Cost on the paper's camera, 81 planes, shared 2-core machine: 6.1 s median of 3 runs,
    of which the quadrature 4.7 s and 5 feature sizes 1.5 s (about 0.35 s per feature size
    in a 40-size sweep); peak process memory 626 MB, 378 MB of it before the map
    (``python experiments/depth_resolution.py``, ``results/depth_resolution.md``).
    """
    from .quadrature import QUADRATURE_NODES, exact_kernels
    camera = PAPER_CAMERA if camera is None else camera
    near_mm, far_mm, spacing_mm, feature_mm = stack_settings(camera, near_mm, far_mm, spacing_mm, feature_mm)
    if axis not in AXES:
        raise ValueError(f"axis must be one of {AXES}. Received: {axis!r}")
    depths = stack_depths(near_mm, far_mm, spacing_mm)
    if depths.size < 2:
        raise ValueError(f"the stack from {near_mm:g} to {far_mm:g} mm every {spacing_mm:g} mm has one plane: give "
                         "a spacing below far - near")
    t0 = time.perf_counter()
    kern = exact_kernels(camera, depths, effects=effects,
                         quadrature_nodes=QUADRATURE_NODES if quadrature_nodes is None else quadrature_nodes)
    res = resolution_from_kernels(kern, feature_mm, conditions, axis, camera)
    return dataclasses.replace(res, setup_s=time.perf_counter() - t0 - res.map_s)


def plot_depth_resolution(path, res: DepthResolution, title: str = "") -> None:
    """Figure: smallest resolvable spacing against feature size, one curve per condition
    number (the median over positions interpolated, dots on the stack's spacings, the
    worst position dashed), log axes; PNG written atomically.

    Parameters
    ----------
    path : str or Path
    res : DepthResolution
    title : str
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    span = float(res.depths_mm[-1] - res.depths_mm[0])
    fig, ax = plt.subplots(figsize=(6.0, 4.3), layout="constrained")
    for ci, c in enumerate(res.conditions):
        line, = ax.loglog(res.feature_mm, res.spacing_interp_mm[:, ci], "-",
                          label=f"cond <= {c:g}: median over positions (interpolated)")
        ax.loglog(res.feature_mm, res.spacing_median_mm[:, ci], "o", ms=2.5, color=line.get_color(),
                  label=f"cond <= {c:g}: median, on the stack's spacings")
        ax.loglog(res.feature_mm, res.spacing_worst_mm[:, ci], "--", color=line.get_color(), lw=1,
                  label=f"cond <= {c:g}: worst position, on the stack's spacings")
    step = float(res.spacings_mm[0])
    for level, text in ((span, f"stack length {span:g} mm"), (step, f"stack spacing {step:g} mm")):
        ax.axhline(level, color="0.5", lw=0.8, ls=":")
        ax.text(float(np.nanmax(res.feature_mm)), level * 1.04, text, fontsize=7, color="0.4", ha="right", va="bottom")
    ax.set_xlabel("feature size (half a period), mm")
    ax.set_ylabel("smallest resolvable plane spacing, mm")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(title or f"depth resolution, {res.depths_mm.size} planes {res.depths_mm[0]:+g} to "
                 f"{res.depths_mm[-1]:+g} mm, frequency along {res.axis}", fontsize=8)
    path = os.fspath(path)
    tmp = path + ".partial.png"
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
