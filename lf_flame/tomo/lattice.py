"""The exact operator of decoded views: on the lenslets' own lattice, square or hexagonal, with
decoding's interpolation.

Decoding (:func:`lf_flame.real.decoding.decode`) reads each view sample by bilinear interpolation
at a position that falls between pixels wherever the lenslet grid's pitch is not a whole number
of pixels: a sample a fraction ``f`` of the way to the next pixel mixes the two with weights
``1 - f`` and ``f``. Over the lenslets that is a blur of their images (a triangle one pixel wide
each side where the phases ``f`` spread evenly: :func:`lf_flame.real.view_grid.interpolation_phases`),
which the square camera's operator, built for pixels read whole, leaves out; on a grid whose
lenslet centres sit on pixel centres it is nil. Here each ray's pixel is the one before or after
the sample's position with the interpolation's weights, at a phase drawn from the decoded views'
own (their mean over the lenslets, per axis; what varies from lenslet to lenslet is left out).

A hexagonal microlens array's views sample the object on the lattice of its lenslets, and decoding
resamples them onto a square grid (:func:`lf_flame.real.view_grid.hex_to_square`) so that
refocusing and the depth search run unchanged; but that interpolation blurs the views by an
amount that depends on each sample's place in its lattice triangle, which no convolution on the
square grid models. So a hexagonal camera's planes are solved on its lattice itself: the map to
the views on the lenslets' own lattice is still a convolution per view and plane, as every
lenslet sees the same texel offsets (the argument of :mod:`lf_flame.tomo.exact`); only the
lattice differs.

Storage (axial, or skew, coordinates): site ``(j, i)`` of the hexagonal lattice lies at
``(j sqrt(3)/2, i + j/2)`` pitches (row, column), so translation by a lattice vector is a shift
of the array and the FFT convolutions of :class:`~lf_flame.tomo.exact.ExactOperator` apply as
they are. The decoded views, rows of lenslets each shifted by half a pitch from the one before
(the calibration's offset rows), become a parallelogram in that array (:func:`to_axial`); the
array's other samples are missing data, left out of the fit like clipped ones. The planes fill
the whole array; ``subsamples`` = s puts s x s sites of the s-times finer lattice in each
lenslet's (the polyphase grouping of :func:`lf_flame.tomo.quadrature._phase_kernels`).

The kernels: per view and plane, the mean over a pixel's rays (the pixel's area, shifted by the
interpolation, times the lenslet's cell, square or hexagonal as the renderer draws it:
:func:`hexagon_points`) of aperture x cos^4 x [the ray reads the plane at site offset (m, n)],
from the same affine ray chain as the square camera's
(:func:`lf_flame.tomo.quadrature.chain_coefficients`). Neither the interpolation's two pixels nor the
hexagon's nearest site are separable by axis, so the mean is taken over the points of a
low-discrepancy sequence (:func:`rd_points`, the renderer's: the same kernels every run) rather
than by the closed-form quadrature of :func:`~lf_flame.tomo.quadrature.exact_kernels`; on a square
lattice without interpolation the two agree within 3e-3 of the taps' sum (L1) at 2^14 points and
1e-3 at 2^16 (``tests/test_lattice_operator.py``).

A hexagonal lattice's planes are resampled onto the decoded square grid afterwards
(:meth:`LatticeOperator.to_square`, barycentric in the fine lattice's triangles), where the depth
search, the scores and the files of every other camera live.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..simulate.scenes import FLAME_EFFECTS
from ..simulate.layers import Effects
from . import _lattice_kernels
from .exact import ExactOperator
from .quadrature import ExactKernels, _phase_kernels, chain_coefficients, sub_view_chain
from .operator import plane_grid

#: A hexagonal lattice's row spacing, pitches.
_H = math.sqrt(3) / 2
#: Points per view and plane of the kernels' mean (:func:`rd_points`): on a square lattice the taps
#: differ from the exact quadrature's by 7e-3 of their sum (L1) at 2^12, 3e-3 at 2^14, 1e-3 at 2^16 and
#: 5e-4 at 2^18 (``tests/test_lattice_operator.py`` checks 2^16).
KERNEL_POINTS = 2 ** 14
LAYOUTS = ("hex", "square")


def nearest_site(y, x, layout: str = "hex"):
    """The lattice site nearest to points ``(y, x)`` (pitches from site (0, 0), rows down).

    Parameters
    ----------
    y, x : ndarray
        Points, pitches.
    layout : {'hex', 'square'}
        ``hex``: site ``(j, i)`` at ``(j sqrt(3)/2, i + j/2)``; ``square``: at ``(j, i)``.

    Returns
    -------
    j, i : ndarray of int64
        Axial indices of the nearest site (its Voronoi cell: the hexagon, or the square).

    Raises
    ------
    ValueError
        An unknown layout.
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}. Received: {layout!r}")
    y, x = np.broadcast_arrays(np.asarray(y, np.float64), np.asarray(x, np.float64))
    j, i = np.empty(y.shape, np.int64), np.empty(y.shape, np.int64)
    _lattice_kernels.nearest_sites(np.ascontiguousarray(y).ravel(), np.ascontiguousarray(x).ravel(), layout == "hex",
                                   j.reshape(-1), i.reshape(-1))
    return j, i


def hexagon_points(a_row, a_col):
    """Uniform points of the unit square ``[-1/2, 1/2)^2`` mapped onto the hexagonal cell of a
    lattice site, uniform there: the rhombus ``(1, 0), (1/2, sqrt(3)/2)`` (column, row) they span,
    each point moved into the hexagon by the lattice vector that brings it nearest the centre
    (the renderer's draw, :func:`lf_flame.simulate._kernels.render_points`).

    Returns
    -------
    rows, cols : ndarray
        Offsets from the cell's centre, pitches.
    """
    col = np.asarray(a_row, np.float64) + 0.5 * np.asarray(a_col, np.float64)
    row = _H * np.asarray(a_col, np.float64)
    best_c, best_r, best_d = np.zeros_like(col), np.zeros_like(row), col ** 2 + row ** 2
    for vc, vr in ((1.0, 0.0), (-1.0, 0.0), (0.5, _H), (-0.5, -_H), (-0.5, _H), (0.5, -_H)):
        d = (col - vc) ** 2 + (row - vr) ** 2
        closer = d < best_d
        best_c, best_r, best_d = np.where(closer, vc, best_c), np.where(closer, vr, best_r), np.where(closer, d, best_d)
    return row - best_r, col - best_c


def rd_points(n: int, dims: int) -> np.ndarray:
    """The first ``n`` points of the ``dims``-dimensional R_d low-discrepancy sequence in [0, 1)^dims:
    ``frac(1/2 + k alpha)``, ``alpha_i = phi^-i``, phi the real root of ``x^(dims + 1) = x + 1``
    (M. Roberts, "The unreasonable effectiveness of quasirandom sequences", 2018), the sequence the
    renderer draws its rays from (:mod:`lf_flame.simulate._kernels`). Shape (n, dims), float64."""
    phi = 2.0
    for _ in range(60):                                    # Newton on x^(d+1) - x - 1
        phi -= (phi ** (dims + 1) - phi - 1) / ((dims + 1) * phi ** dims - 1)
    alpha = phi ** -np.arange(1.0, dims + 1)
    return (0.5 + np.arange(1, n + 1)[:, None] * alpha) % 1.0


def lattice_kernels(camera, depths_mm, shape, *, layout: str = "hex", subsamples: int = 1,
                    points: int = KERNEL_POINTS, effects: Effects = FLAME_EFFECTS, interpolation=None,
                    view_shifts=None) -> ExactKernels:
    """The exact map's kernels on a lenslet lattice, by quasi-Monte Carlo over each pixel's rays.

    Parameters
    ----------
    camera : PlenopticCamera
        The decoded views' square camera (:func:`lf_flame.real.own_camera.views_camera`): its optics,
        pitch and views; its grid's size is not used.
    depths_mm : sequence of float
        The planes' depths, mm from the focus distance.
    shape : (int, int)
        The views' axial array, rows x columns of lenslets (:func:`to_axial`).
    layout : {'hex', 'square'}
        The lenslets' lattice and cells (the square one checks this route against
        :func:`lf_flame.tomo.quadrature.exact_kernels`).
    subsamples : int
        Sites of the s-times finer lattice per lenslet and axis.
    points : int
        Points of the R_d sequence (:func:`rd_points`) per view and plane.
    effects : Effects
        Aperture and cos^4 as asked (occlusion and crosstalk off).
    interpolation : (ndarray of shape (2, M), int) or None
        Decoding's bilinear interpolation (:attr:`lf_flame.real.lightfield.LightField.interpolation`):
        the samples' phases between pixels per sensor axis and the pixels binned per view sample.
        Each ray's pixel is then the one before or after the sample's position, with the
        interpolation's weights, at a phase drawn from these (their mean over the lenslets; per
        axis). None: each sample is one pixel (simulated views).
    view_shifts : sequence of float or None
        Sub-views of each view, its pixel moved by each shift (view steps;
        :func:`lf_flame.tomo.quadrature.sub_view_chain`), as :func:`lf_flame.tomo.quadrature.exact_kernels`'.

    Returns
    -------
    ExactKernels
        ``dims`` (P, s rows, s cols) and ``dimsd`` (N, N, rows, cols) on the axial array; the
        per-pixel weights 1 (the cos^4 drift across the field is the white image's, divided out
        by decoding and left out of data and model alike).

    Raises
    ------
    ValueError
        An unknown layout, occlusion or crosstalk on, fewer than one subsample, a plane the
        camera cannot image.
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}. Received: {layout!r}")
    if effects.occlusion or effects.crosstalk:
        raise ValueError("the exact operator needs occlusion and crosstalk off (flames are optically thin)")
    if int(subsamples) != subsamples or subsamples < 1:
        raise ValueError(f"subsamples must be a positive integer. Received: {subsamples!r}")
    s = int(subsamples)
    depths = [float(d) for d in np.atleast_1d(depths_mm)]
    R, C = (int(v) for v in shape)
    N, P = camera.pixels_per_lenslet, len(depths)
    sizes = [plane_grid(camera, d, 1.0) for d in depths]
    (cy, ay, ty, _), (cx, ax, tx, _) = chain = chain_coefficients(camera, depths, sizes,
                                                                  (camera.n_rows, camera.n_cols), effects)
    if view_shifts is not None:
        (cy, ay, ty, _), (cx, ax, tx, _) = (sub_view_chain(a, view_shifts) for a in chain)
        N = cy.shape[0]
    u = rd_points(int(points), 8)
    du_y, du_x = u[:, 0] - 0.5, u[:, 1] - 0.5
    if interpolation is not None:      # the pixel after the sample's position with weight f, the one before with 1 - f
        phases, binned = interpolation
        phases = np.asarray(phases, np.float64)
        f_y = phases[0, np.minimum((u[:, 4] * phases.shape[1]).astype(np.int64), phases.shape[1] - 1)]
        f_x = phases[1, np.minimum((u[:, 6] * phases.shape[1]).astype(np.int64), phases.shape[1] - 1)]
        du_y = du_y + np.where(u[:, 5] < f_y, 1.0 - f_y, -f_y) / binned
        du_x = du_x + np.where(u[:, 7] < f_x, 1.0 - f_x, -f_x) / binned
    a_y, a_x = u[:, 2] - 0.5, u[:, 3] - 0.5
    da_y, da_x = hexagon_points(a_y, a_x) if layout == "hex" else (a_y, a_x)
    r2 = (camera.aperture_diameter_mm / 2) ** 2 if effects.aperture else np.inf
    # fine site 0 of a lenslet: at its centre on the hexagonal lattice; on the square one at the first of its
    # s x s cells, as the square camera's polyphase grid (exact_kernels)
    centre = 0.0 if layout == "hex" else (s - 1) / 2
    rays = [np.ascontiguousarray(v, np.float64) for v in (du_y, du_x, da_y, da_x)]
    chain_y, ay, ty, chain_x, ax, tx = (np.ascontiguousarray(v, np.float64) for v in (cy, ay, ty, cx, ax, tx))
    hexagonal = layout == "hex"
    bounds = np.empty((N, 4), np.int64)
    _lattice_kernels.lattice_bounds(chain_y, ay, chain_x, ax, *rays, r2, float(s), centre, hexagonal, bounds)
    lit = bounds[:, 0] <= bounds[:, 1]
    if not lit.any():
        raise ValueError("no pixel's rays pass the main lens's aperture")
    j0, i0 = int(bounds[lit, 0].min()), int(bounds[lit, 2].min())
    h = np.zeros((N, N, P, int(bounds[lit, 1].max()) - j0 + 1, int(bounds[lit, 3].max()) - i0 + 1))
    _lattice_kernels.lattice_taps(chain_y, ay, ty, chain_x, ax, tx, *rays, r2, bool(effects.cos4), float(s), centre,
                                  hexagonal, j0, i0, h)
    m0y, n0x = np.full((N, P), j0, np.int64), np.full((N, P), i0, np.int64)
    if s > 1:
        h, m0y, n0x = _phase_kernels(h, m0y, n0x, s)
    return ExactKernels(h, m0y, n0x, np.ones((N, N, R, C)), tuple(depths),
                        tuple(tuple(float(v) for v in z) for z in sizes), 1.0, (P, s * R, s * C), (N, N, R, C), s)


def to_axial(a: np.ndarray):
    """Arrays on a hexagonal grid's offset rows (row 0 unshifted, odd rows half a pitch right:
    the calibration's grid) in axial storage.

    Parameters
    ----------
    a : ndarray of shape (..., R, C)

    Returns
    -------
    axial : ndarray of shape (..., R, C + (R - 1) // 2)
        Lenslet ``(j, c)`` at column ``c - j // 2 + (R - 1) // 2``; 0 (False) elsewhere.
    inside : ndarray of bool of shape (R, C + (R - 1) // 2)
        Where the array holds a lenslet.
    """
    a = np.asarray(a)
    R, C = a.shape[-2:]
    off = (R - 1) // 2
    out = np.zeros(a.shape[:-1] + (C + off,), a.dtype)
    inside = np.zeros((R, C + off), bool)
    for j in range(R):
        c0 = off - j // 2
        out[..., j, c0:c0 + C] = a[..., j, :]
        inside[j, c0:c0 + C] = True
    return out, inside


class LatticeOperator(ExactOperator):
    """Decoded views as a linear map of the emission on their lenslets' lattice, with decoding's
    interpolation (module docstring): an :class:`~lf_flame.tomo.exact.ExactOperator` (hexagonal:
    whose planes and views are axial arrays), so every solver of :mod:`lf_flame.tomo.solvers`
    (admm included) takes it.

    Parameters
    ----------
    camera : PlenopticCamera
        The decoded views' square camera (:func:`lf_flame.real.own_camera.views_camera`).
    depths_mm : sequence of float
    lattice_shape : (int, int)
        The decoded views' grid, rows x lenslets per row (hexagonal: offset rows).
    layout : {'square', 'hex'}
    precision, workers, subsamples
        As :class:`~lf_flame.tomo.exact.ExactOperator`.
    points : int
        Points of the kernels' mean (:data:`KERNEL_POINTS`).
    interpolation : (ndarray, int) or None
        Decoding's interpolation (:func:`lattice_kernels`;
        :attr:`lf_flame.real.lightfield.LightField.interpolation`).
    sample_offsets : ndarray of shape (N, N, R, C, 2) or None
        Each lattice sample's pixel from its view's place (a colour capture's nearest pixels,
        :attr:`lf_flame.real.lightfield.LightField.sample_offsets`), on the lattice's offset rows;
        modelled by ``offset_bins`` sub-views per view and axis as
        :class:`~lf_flame.tomo.exact.ExactOperator`'s.
    offset_bins : int or None
        As :class:`~lf_flame.tomo.exact.ExactOperator`'s (None: as the planes need).

    Attributes
    ----------
    dims : (P, s R, s C')
        The planes (hexagonal: axial, ``C' = C + (R - 1) // 2``; square: ``C' = C``).
    dimsd : (N, N, R, C')
        The views (hexagonal: axial, :func:`to_axial`).
    lattice_shape : (int, int)
    layout : str
    inside : ndarray of bool of shape (R, C')
        The array's lenslets (hexagonal: the rest is missing data).

    Raises
    ------
    ValueError
        As :func:`lattice_kernels`; a lattice of fewer than 2 x 2 lenslets.
    """

    _SHARED = ExactOperator._SHARED + ("lattice_shape", "layout", "inside", "points", "interpolation")

    def __init__(self, camera, depths_mm, lattice_shape, *, layout: str = "hex", precision: str = "float32",
                 workers: int | None = None, subsamples: int = 1, points: int = KERNEL_POINTS, interpolation=None,
                 sample_offsets=None, offset_bins: int | None = None):
        R, C = (int(v) for v in lattice_shape)
        if R < 2 or C < 2:
            raise ValueError(f"a lenslet lattice of {R} x {C} lenslets is too small")
        if layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}. Received: {layout!r}")
        self.lattice_shape, self.layout, self.points, self.interpolation = (R, C), layout, int(points), interpolation
        self.inside = to_axial(np.zeros((R, C)))[1] if layout == "hex" else np.ones((R, C), bool)
        if sample_offsets is not None and layout == "hex":     # on the axial array, as the views
            if np.shape(sample_offsets)[2:4] != (R, C):
                raise ValueError(f"sample_offsets must be of the lattice views' shape (N, N, {R}, {C}, 2). Received: "
                                 f"{np.shape(sample_offsets)}")
            sample_offsets = np.moveaxis(to_axial(np.moveaxis(np.asarray(sample_offsets), -1, 0))[0], 0, -1)
        super().__init__(camera, depths_mm, precision=precision, workers=workers, subsamples=subsamples,
                         sample_offsets=sample_offsets, offset_bins=offset_bins)

    def _kernels(self, camera, depths_mm, *, effects, subsamples, view_shifts=None, **_):
        return lattice_kernels(camera, depths_mm, self.inside.shape, layout=self.layout, subsamples=subsamples,
                               points=self.points, effects=effects, interpolation=self.interpolation,
                               view_shifts=view_shifts)

    def to_square(self, planes, rows: int, cols: int) -> np.ndarray:
        """A hexagonal lattice's planes resampled onto the decoded square grid (barycentric in the fine
        lattice's triangles; :func:`lf_flame.real.view_grid.hex_to_square`'s geometry: square row
        ``r`` at ``r`` pitches below lenslet (0, 0), column ``c`` at ``c + 1/2`` right of it).

        Parameters
        ----------
        planes : ndarray of shape (P, s R, s C')
            On the lattice's sites (``dims``: ``s`` its ``subsamples``) or on a grid ``s`` times as
            fine as the lenslets' for another ``s`` (binned to the lenslets: 1).
        rows, cols : int
            The square grid's lenslets (``s`` samples each per axis).

        Returns
        -------
        ndarray of shape (P, s rows, s cols), float64

        Raises
        ------
        ValueError
            A square lattice (its planes are on that grid).
        """
        self._hexagonal("to_square")
        x = np.asarray(planes)
        if x.ndim != 3:
            x = x.reshape(self.dims)
        s, off = x.shape[1] // self.lattice_shape[0], (self.lattice_shape[0] - 1) // 2
        if s < 1 or x.shape[1:] != (s * self.inside.shape[0], s * self.inside.shape[1]):
            raise ValueError(f"planes of shape {x.shape} are not on this lattice's sites (P, s x "
                             f"{self.inside.shape[0]}, s x {self.inside.shape[1]})")
        y, xx = np.meshgrid((np.arange(s * rows) + 0.5) / s - 0.5, (np.arange(s * cols) + 0.5) / s, indexing="ij")
        j = y * s / _H                               # fine lattice rows, fractional
        i = s * xx - j / 2 + s * off                 # fine axial columns
        j0, i0 = np.floor(j), np.floor(i)
        fj, fi = j - j0, i - i0
        lower = fi + fj < 1
        verts = [(np.where(lower, j0, j0 + 1), np.where(lower, i0, i0 + 1), np.where(lower, 1 - fi - fj, fi + fj - 1)),
                 (j0, i0 + 1, np.where(lower, fi, 1 - fj)),
                 (j0 + 1, i0, np.where(lower, fj, 1 - fi))]
        out = np.zeros((x.shape[0],) + y.shape)
        for vj, vi, w in verts:
            out += w * x[:, np.clip(vj, 0, x.shape[1] - 1).astype(int), np.clip(vi, 0, x.shape[2] - 1).astype(int)]
        return out

    def _hexagonal(self, what):
        if self.layout != "hex":
            raise ValueError(f"{what} resamples a hexagonal lattice's planes; these are on a square grid")

    def from_square(self, planes) -> np.ndarray:
        """Square-grid planes (P, s rows, s cols) at this lattice's fine sites, each from the square
        sample it falls in (nearest; 0 outside): for masks such as admm's support.

        Returns
        -------
        ndarray of shape ``dims``, the input's dtype.
        """
        self._hexagonal("from_square")
        s, off = self.subsamples, (self.lattice_shape[0] - 1) // 2
        sq = np.asarray(planes)
        j, i = np.meshgrid(np.arange(self.dims[1]), np.arange(self.dims[2]), indexing="ij")
        y, x = j * _H / s, (i - s * off) / s + j / (2 * s)
        r, c = np.floor(s * (y + 0.5)).astype(int), np.floor(s * x).astype(int)
        ok = (r >= 0) & (r < sq.shape[1]) & (c >= 0) & (c < sq.shape[2])
        out = np.zeros((sq.shape[0],) + r.shape, sq.dtype)
        out[:, ok] = sq[:, r[ok], c[ok]]
        return out


@dataclasses.dataclass
class LatticeSolve:
    """:func:`solve_on_lattice`'s result.

    Attributes
    ----------
    op : LatticeOperator
        On the hexagonal lattice.
    rec : Reconstruction
        The solve on the lattice (planes: ``op.dims``, axial).
    square : Reconstruction
        The same planes resampled onto the decoded square grid (:meth:`LatticeOperator.to_square`).
    data, leave_out : ndarray of shape ``op.dimsd``
        The lattice views as the operator's data and the samples left out (clipped, dark, no lenslet).
    """

    op: LatticeOperator
    rec: object
    square: object
    data: np.ndarray
    leave_out: np.ndarray


def solve_on_lattice(lf, rec, op, support=None) -> LatticeSolve:
    """A hexagonal camera's planes solved again on its own lattice, with the knobs the square grid's
    admm chose.

    Parameters
    ----------
    lf : lf_flame.real.lightfield.LightField
        Decoded views of a hexagonal grid with their lattice views (``lf.lattice_views``).
    rec : Reconstruction
        admm's solve of ``lf.views`` (the square grid) at the planes' depths: its knobs
        (fills, weights, start, tolerance) and its support are taken.
    op : ExactOperator
        That solve's operator (its ``subsamples``).
    support : ndarray of bool of shape ``op.dims`` or None
        That solve's support (:func:`lf_flame.tomo.found_planes.found_support`), taken to the
        lattice by :meth:`LatticeOperator.from_square`.

    Returns
    -------
    LatticeSolve

    Raises
    ------
    ValueError
        A light field without lattice views, a solve that was not admm's.
    """
    from .solvers import reconstruct
    if lf.lattice_views is None:
        raise ValueError(f"{lf.source}: no hexagonal lattice views to solve on")
    if rec.solver != "admm":
        raise ValueError(f"the lattice solve takes admm's knobs; this solve is {rec.solver!r}")
    s = getattr(op, "subsamples", 1)
    hop = hexagonal_operator(lf, rec.depths_mm, subsamples=s)
    data, leave_out = lattice_problem(lf, hop)
    st = rec.settings
    knobs = dict(iters=int(st["iters"]), tv=st["tv"], lam=st["lam"], l1=st["l1"], start=st["start"], tol=st["tol"])
    if hop.offset_bins is not None:      # samples off the views' grid: admm's fills and tolerance for them
        knobs.update(iters=None, tol=None)
    lat = reconstruct(data, hop, "admm", saturation=leave_out, unit=lf.unit,
                      support=None if support is None else hop.from_square(support), **knobs)
    lat.settings.update(lattice="hexagonal", noise=st.get("noise", math.nan))
    planes = hop.to_square(lat.planes, op.dims[1] // s, op.dims[2] // s)
    square = dataclasses.replace(lat, planes=planes, sample_mm=rec.sample_mm, settings=dict(lat.settings))
    return LatticeSolve(hop, lat, square, data, leave_out)


def hexagonal_operator(lf, depths_mm, **kw) -> LatticeOperator:
    """The :class:`LatticeOperator` of a decoded hexagonal grid's lattice views at ``depths_mm`` (mm),
    with decoding's interpolation (none for a colour capture's nearest pixels) and the light field's
    sample offsets (a colour capture's); ``kw`` as there (``subsamples``, ``precision``,
    ``sample_offsets`` in place of the light field's).

    Raises
    ------
    ValueError
        A light field without lattice views.
    """
    if lf.lattice_views is None:
        raise ValueError(f"{lf.source}: no hexagonal lattice views to solve on")
    kw.setdefault("sample_offsets", lf.sample_offsets)
    return LatticeOperator(lf.camera, depths_mm, lf.lattice_views.shape[2:], interpolation=lf.interpolation, **kw)


def lattice_problem(lf, op: LatticeOperator):
    """A decoded hexagonal grid's lattice views as ``op``'s data (axial, :func:`to_axial`), and the
    samples to leave out: clipped, dark (:func:`lf_flame.tomo.decoded.decoded_problem`) or where
    the axial array holds no lenslet.

    Returns
    -------
    data : ndarray of shape ``op.dimsd``, float64
    leave_out : ndarray of bool of shape ``op.dimsd``
    """
    from .decoded import decoded_problem
    views, _ = to_axial(lf.lattice_views)
    clipped = None if lf.lattice_leave_out is None else to_axial(lf.lattice_leave_out)[0]
    data, leave_out = decoded_problem(views, op, clipped)
    return data, leave_out | ~op.inside
