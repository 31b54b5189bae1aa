"""3-D emission reconstruction: each plane's own light, not its blurred focal stack.

The one place for reconstruction (issue 25). A refocused plane is the plane in focus
plus every other plane's defocused light; flames are optically thin (they emit and do
not occlude), so a light field is a *linear* function of the emission on the planes.
With its ray samples fixed, the simulator's backward tracer (:func:`lf_flame.simulate.render`,
kernel :func:`lf_flame._simulate_kernels.render_backward`) *is* that linear map ``A``,
from emission on ``P`` planes to sub-aperture views. :class:`EmissionOperator` wraps it
and its exact transpose (the same kernel scattering each pixel's value back to the
texels its rays read) as a :class:`pylops.LinearOperator`; the solvers are PyLops's and
PyProximal's (:func:`reconstruct`). The operator records its rays once (the same kernel
writing each ray's weight and texels) and applies that record as a sparse matrix
(:mod:`lf_flame._reconstruct_kernels`): every solver iterates on the same matrix, about
twice as fast as tracing anew.

The grid of each plane (:func:`plane_grid`): one sample per lenslet footprint at the
plane's depth, ``p z / d`` mm (:func:`lf_flame.diagnostics.lenslet_size_mm`), over the
lenslet grid's field of view there. That is the resolution a plenoptic 1.0 camera
samples an in-focus plane at (one ray bundle per lenslet), and on it the refocused
plane and the reconstructed plane share pixels, so every diagnostic reads both.

Sources: the forward model is the paper's ray-transfer-matrix camera (Eq. 1, SPEC.md);
light-field tomography of flames by ray tracing + (damped) LSQR: Sun, Hossain, Xu et
al., Opt. Commun. 390 (2017); SIRT / Chambolle-Pock with TV and non-negativity:
Viganò et al., Opt. Express (2018) (plenoptomos); Richardson-Lucy as in LF microscopy
(Broxton et al., Opt. Express 21 (2013); napari-LF).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pylops
import pyproximal
from pylops.optimization.basic import lsqr
from pyproximal.optimization.primal import ProximalGradient
from pyproximal.optimization.primaldual import PrimalDual
from tqdm.auto import tqdm

from . import _reconstruct_kernels, _simulate_kernels
from .camera import PlenopticCamera
from .scenes import Effects, Layer, Scene
from .refocus import raw_to_views, views_to_raw
from .simulate import NO_TABLE, _stack_layers, _validate_sampling, trace_coefficients

#: Parallel blocks of sensor rows of the adjoint, each scattering into its own buffer:
#: fixed, so the adjoint's sum is bit-identical at any thread count.
ADJOINT_BLOCKS = 8
#: The flame scenes' effects (optically thin emitters seen through the aperture, cos^4).
FLAME_EFFECTS = Effects(aperture=True, cos4=True, occlusion=False)
#: Largest ray table (bytes: 4 per ray and plane for the texel, 4 per ray for the weight) an
#: :class:`EmissionOperator` records; a larger map is traced anew at every application.
#: The paper's camera, 4 planes, 4 rays per pixel: 292 MB.
RAY_TABLE_MAX_BYTES = 1 << 30


def plane_grid(camera: PlenopticCamera, depth_offset_mm: float, margin: float = 1.0):
    """Frame (height, width) in mm of the reconstruction grid of the plane at ``dz``.

    The grid has ``(n_rows, n_cols)`` samples (one per lenslet) over the lenslet grid's
    field of view at that depth (:meth:`~lf_flame.camera.PlenopticCamera.field_of_view_mm`)
    times ``margin``, centred on the optical axis.

    Raises
    ------
    ValueError
        A depth that is not finite or lies at or inside the main lens's focal length.
    """
    dz = float(depth_offset_mm)
    if not math.isfinite(dz):
        raise ValueError(f"plane depth must be finite. Received: {depth_offset_mm!r}")
    z = camera.object_distance_mm(dz)
    if z <= camera.main_focal_mm:
        raise ValueError(f"a plane at {dz:+g} mm (object distance {z:g} mm) lies at or inside the main lens's "
                         f"focal length {camera.main_focal_mm:g} mm: the camera cannot image it")
    h, w = camera.field_of_view_mm(dz)
    return h * margin, w * margin


class EmissionOperator(pylops.LinearOperator):
    """The light field as a linear map of the emission on ``P`` planes.

    ``A x`` renders sub-aperture views of ``x`` with the simulator's backward tracer
    (the same kernel and the same rays as :func:`lf_flame.simulate.render`, noise-free,
    no saturation); ``A^T y`` is its exact transpose: the same rays carry each view
    pixel's value back to the texels they read, with the same weights (aperture,
    cos^4, crosstalk). Both are float64 at the interface, float32 radiance inside (as
    the renderer).

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid (square, unrotated, integer pitch).
    depths_mm : sequence of float
        Depth offsets (mm from the focal plane, > 0 farther) of the ``P`` planes.
    grid_shape : (int, int) or None
        Samples (rows, columns) of every plane; None: ``(n_rows, n_cols)``, one per lenslet.
    sizes_mm : sequence of P (float, float) or None
        Height and width (mm) each plane's grid covers; None: :func:`plane_grid` with ``margin``.
    centres_mm : sequence of P (float, float) or None
        Centre (y up, x right; mm) of each grid; None: the optical axis.
    margin : float
        Field-of-view factor of the default grids.
    effects : Effects
        What the camera does to each ray (aperture, cos^4, crosstalk); occlusion must be
        off (the map is linear in emission only for optically thin scenes).
    rays_per_pixel, seed : int
        The renderer's ray samples (:func:`lf_flame.simulate.render`).
    ray_table : bool
        Record the map once, ray by ray (:attr:`ray_table_bytes`, at the first application),
        and apply it from the record: the same rays and weights; on the paper's camera A is
        2x and A^T 3.7x faster than traced, a pd-tv solve 1.9x (``python
        experiments/reconstruct.py --stage timing``). Skipped above :data:`RAY_TABLE_MAX_BYTES`.

    Attributes
    ----------
    dims : (P, rows, cols)
        Model shape (axis order: plane as ``depths_mm``, then rows down, columns right).
    dimsd : (N, N, R, C)
        Data shape: the views of :func:`lf_flame.refocus.raw_to_views`.
    ray_table_bytes : int
        Size of the ray-by-ray record (texel indices and weights) before compression.

    Raises
    ------
    ValueError
        A non-perfect lenslet grid, no planes, a plane the camera cannot image, a
        non-positive grid, occlusion on, bad sampling.

    Notes
    -----
    Traced (``ray_table=False``), one matvec costs one render of ``x`` (its content box
    culled, exactly) and one rmatvec the same rays again, scattering into
    :data:`ADJOINT_BLOCKS` buffers. Recorded, the tracer runs once, writing each ray's
    weight and texel indices (:mod:`lf_flame._reconstruct_kernels`); each application is
    then a gather or a scatter over that record, in float64.
    ``pylops.utils.dottest`` holds to float rounding (``tests/test_reconstruct.py``).
    """

    def __init__(self, camera: PlenopticCamera, depths_mm, *, grid_shape=None, sizes_mm=None, centres_mm=None,
                 margin: float = 1.0, effects: Effects = FLAME_EFFECTS, rays_per_pixel: int = 4, seed: int = 0,
                 ray_table: bool = True):
        if not camera.perfect_grid:
            raise ValueError("the emission operator needs a perfect lenslet grid (square, unrotated, integer "
                             "pitch); decode the capture to such views first (lf_flame.decode)")
        if effects.occlusion:
            raise ValueError("occlusion makes the light field non-linear in the emission: flames are optically "
                             "thin, set Effects(occlusion=False)")
        depths = [float(d) for d in np.atleast_1d(np.asarray(depths_mm, dtype=np.float64))]
        if not depths:
            raise ValueError("depths_mm is empty: give at least one plane")
        gr, gc = (camera.n_rows, camera.n_cols) if grid_shape is None else (int(v) for v in grid_shape)
        if gr < 1 or gc < 1:
            raise ValueError(f"grid_shape must be positive. Received: {grid_shape!r}")
        sizes = [plane_grid(camera, d, margin) for d in depths] if sizes_mm is None else list(sizes_mm)
        centres = [(0.0, 0.0)] * len(depths) if centres_mm is None else list(centres_mm)
        if len(sizes) != len(depths) or len(centres) != len(depths):
            raise ValueError(f"{len(depths)} depths but {len(sizes)} sizes and {len(centres)} centres")
        zero = np.zeros((gr, gc), np.float32)
        scene = Scene("operator", tuple(Layer(zero, None, d, tuple(c), tuple(s))
                                        for d, s, c in zip(depths, sizes, centres)), effects)
        _validate_sampling(rays_per_pixel, seed)
        for d in depths:
            plane_grid(camera, d)          # raises for a plane the camera cannot image
        layers, z, _, _ = _stack_layers(camera, scene)   # nearest first
        order = sorted(range(len(depths)), key=lambda k: depths[k])
        self._ky, self._kx = trace_coefficients(camera, layers, z)
        self._order = np.asarray(order)    # kernel layer j is plane order[j]
        self.camera, self.effects = camera, effects
        self.depths_mm = tuple(depths)
        self.sizes_mm = tuple(tuple(float(v) for v in s) for s in sizes)
        self.centres_mm = tuple(tuple(float(v) for v in c) for c in centres)
        self.rays_per_pixel, self.seed = int(rays_per_pixel), int(seed)
        n = camera.pixels_per_lenslet
        super().__init__(dtype=np.float64, dims=(len(depths), gr, gc), dimsd=(n, n, camera.n_rows, camera.n_cols))
        H, W = camera.sensor_shape
        self.ray_table_bytes = H * W * self.rays_per_pixel * 4 * (len(depths) + 1)
        self._use_table = bool(ray_table) and self.ray_table_bytes <= RAY_TABLE_MAX_BYTES
        self._table = None

    # ---- the kernel, both ways ----------------------------------------------------
    def _kernel(self, rad, box, adjoint, y_raw, grad, record=False, table=NO_TABLE):
        fx, cam = self.effects, self.camera
        out = np.empty(cam.sensor_shape, np.float32)
        _simulate_kernels.render_backward(
            self._ky, self._kx, cam.pixels_per_lenslet, rad, np.zeros((1, 1, 1), np.float32), box, False,
            cam.aperture_diameter_mm / 2 if fx.aperture else -1.0, bool(fx.cos4), 3 if fx.crosstalk else 1,
            self.rays_per_pixel, self.seed, out, adjoint, y_raw, grad, record, *table)
        return out

    def _trace_every_texel(self, adjoint, y_raw, grad, record=False, table=NO_TABLE):
        """The kernel with no culling (every plane's box its whole grid): the adjoint, or the record."""
        P, gr, gc = self.dims
        box = np.tile(np.array([0, gr, 0, gc], np.int64), (P, 1))
        self._kernel(np.zeros((P, gr, gc), np.float32), box, adjoint, y_raw, grad, record, table)

    def _ray_table(self):
        """The map recorded ray by ray, as compressed rows (:mod:`lf_flame._reconstruct_kernels`),
        once; None when the operator traces (``ray_table`` off, or over the size limit)."""
        if self._use_table and self._table is None:
            (H, W), K = self.camera.sensor_shape, self.rays_per_pixel
            rays = (np.full((H, W, K, self.dims[0]), -1, np.int32), np.zeros((H, W, K), np.float32))
            self._trace_every_texel(False, np.zeros((1, 1)), np.zeros((1, 1)), True, rays)
            self._table = _reconstruct_kernels.ray_table_to_csr(*rays, self.camera.pixels_per_lenslet, ADJOINT_BLOCKS)
        return self._table

    def _matvec(self, x):
        P, gr, gc = self.dims
        table = self._ray_table()
        if table is not None:
            out = np.empty(self.shape[0])
            xk = np.ascontiguousarray(np.reshape(x, self.dims)[self._order], dtype=np.float64).ravel()
            _reconstruct_kernels.csr_forward(*table, xk, ADJOINT_BLOCKS, out)
            return out
        rad = np.ascontiguousarray(np.reshape(x, self.dims)[self._order], dtype=np.float32)
        nz = rad != 0
        box = np.zeros((P, 4), np.int64)
        for k in range(P):
            rows, cols = np.flatnonzero(nz[k].any(axis=1)), np.flatnonzero(nz[k].any(axis=0))
            if rows.size:
                box[k] = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        raw = self._kernel(rad, box, False, np.zeros((1, 1)), np.zeros((1, 1)))
        return raw_to_views(raw, self.camera.pixels_per_lenslet).astype(np.float64).ravel()

    def _rmatvec(self, y):
        P, gr, gc = self.dims
        grad = np.zeros((ADJOINT_BLOCKS, P * gr * gc))
        table = self._ray_table()
        if table is not None:
            _reconstruct_kernels.csr_adjoint(*table, np.ascontiguousarray(y, dtype=np.float64).ravel(), grad)
        else:
            self._trace_every_texel(True, views_to_raw(np.reshape(np.asarray(y, np.float64), self.dimsd)), grad)
        out = np.empty((P, gr, gc))
        out[self._order] = grad.sum(axis=0).reshape(P, gr, gc)
        return out.ravel()

    def normalised_adjoint(self, views) -> np.ndarray:
        """``A^T y / A^T 1``: each sample's mean over the rays that read it, a refocused stack.

        Parameters
        ----------
        views : ndarray of shape (N, N, R, C)

        Returns
        -------
        planes : ndarray of shape (P, rows, cols), float64; 0 where no ray reaches a sample.
        """
        num = self.rmatvec(np.asarray(views, np.float64).ravel())
        den = self.rmatvec(np.ones(self.shape[0]))
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0).reshape(self.dims)


# ---- the truth on a reconstruction grid ----------------------------------------------
def _overlap(src_edges: np.ndarray, dst_edges: np.ndarray) -> np.ndarray:
    """(n_dst, n_src) fraction of each destination cell covered by each source cell
    (1-D, both edge arrays increasing)."""
    lo = np.maximum(dst_edges[:-1, None], src_edges[None, :-1])
    hi = np.minimum(dst_edges[1:, None], src_edges[None, 1:])
    return np.clip(hi - lo, 0.0, None) / np.diff(dst_edges)[:, None]


def resample_layer(layer: Layer, shape, size_mm, centre_mm=(0.0, 0.0)) -> np.ndarray:
    """A layer's radiance averaged over the cells of another grid (area-weighted, exact).

    The renderer reads a texture as piecewise constant (nearest texel), so the average
    of its texels over a cell, weighted by the area they share, is the cell's emission.

    Parameters
    ----------
    layer : Layer
        Texture (rows, cols) over ``layer.size_mm`` about ``layer.centre_mm``.
    shape : (int, int)
        Cells (rows, columns) of the grid.
    size_mm, centre_mm : (float, float)
        Height and width, and centre (y up, x right), of the grid in mm.

    Returns
    -------
    ndarray of shape ``shape``, float64: mean radiance per cell (0 outside the layer).
    """
    (tr, tc), (gr, gc) = layer.radiance.shape, shape
    # both grids' edges in mm, rows measured downward from the top so the edges increase
    src_y = np.linspace(-(layer.centre_mm[0] + layer.size_mm[0] / 2), -(layer.centre_mm[0] - layer.size_mm[0] / 2), tr + 1)
    src_x = np.linspace(layer.centre_mm[1] - layer.size_mm[1] / 2, layer.centre_mm[1] + layer.size_mm[1] / 2, tc + 1)
    dst_y = np.linspace(-(centre_mm[0] + size_mm[0] / 2), -(centre_mm[0] - size_mm[0] / 2), gr + 1)
    dst_x = np.linspace(centre_mm[1] - size_mm[1] / 2, centre_mm[1] + size_mm[1] / 2, gc + 1)
    return _overlap(src_y, dst_y) @ layer.radiance.astype(np.float64) @ _overlap(src_x, dst_x).T


def scene_truth(scene: Scene, op: EmissionOperator) -> np.ndarray:
    """The emission of ``scene`` on the operator's planes: the truth a reconstruction is scored on.

    A scene layer at one of the operator's depths gives that plane its radiance
    (:func:`resample_layer`). Layers between two planes (a volume sampled finer than the
    planes) are shared between the two nearest planes linearly in depth (each plane
    stands for the slab around it); layers outside the planes' range go to the nearest.

    Returns
    -------
    ndarray of shape ``op.dims`` (P, rows, cols), float64.
    """
    d = np.asarray(op.depths_mm)
    order = np.argsort(d)
    ds = d[order]
    truth = np.zeros(op.dims)
    for L in scene.layers:
        k = int(np.searchsorted(ds, L.depth_offset_mm))
        if k == 0 or k == len(ds) or np.isclose(ds[min(k, len(ds) - 1)], L.depth_offset_mm):
            shares = [(order[min(k, len(ds) - 1)], 1.0)]
        else:
            f = (L.depth_offset_mm - ds[k - 1]) / (ds[k] - ds[k - 1])
            shares = [(order[k - 1], 1.0 - f), (order[k], f)]
        for p, wgt in shares:
            truth[p] += wgt * resample_layer(L, op.dims[1:], op.sizes_mm[p], op.centres_mm[p])
    return truth


# ---- solvers ---------------------------------------------------------------------------
#: Solvers of :func:`reconstruct`; "adjoint" is plain refocusing (the baseline).
SOLVERS = ("adjoint", "lsqr", "fista", "pd-tv", "rl")
#: Iterations each solver runs unless told: the fewest within 10 % of the solver's best
#: worst-plane error on validation renders (``results/reconstruct_iters.csv``, ``make reconstruct``).
DEFAULT_ITERS = {"adjoint": 0, "lsqr": 40, "fista": 30, "pd-tv": 40, "rl": 20}
#: TV weight of "pd-tv" unless told (validation renders, as the iterations).
DEFAULT_TV = 0.3
#: "pd-tv" records its residual at the first, every this many and the last iteration (NaN
#: between): each record costs one more ``A``, a third of an iteration.
PD_RESIDUAL_EVERY = 5
#: The solver whose worst validation render is best (``make reconstruct``): the default of ``lf-flame reconstruct``.
DEFAULT_SOLVER = "pd-tv"


@dataclass
class Reconstruction:
    """Emission on planes recovered from one light field (:func:`reconstruct`).

    Attributes
    ----------
    planes : ndarray of shape (P, rows, cols), float64
        Emission (the scene's radiance units) on each plane, rows down, columns right.
    depths_mm : tuple of P float
        Depth offset of each plane (mm from the focal plane).
    sample_mm : tuple of P (float, float)
        Size (height, width) of one grid sample on each plane, mm.
    solver : str
    settings : dict
        The solver's knobs (iterations, damping, TV weight, step, rays per pixel, seed).
    residuals : ndarray of shape (n,)
        Relative data residual ``||A x - y|| / ||y||`` per iteration (for FISTA at the
        point where the gradient is taken; for the primal-dual solver NaN between its
        records, :data:`PD_RESIDUAL_EVERY`), saturated pixels left out.
    time_s : float
        Wall time of the solve (the operator built, the step size found, the iterations).
    """

    planes: np.ndarray
    depths_mm: tuple
    sample_mm: tuple
    solver: str
    settings: dict = field(default_factory=dict)
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    time_s: float = 0.0


class _TrackedL2(pyproximal.L2):
    """``1/2 ||A x - b||^2`` that records the relative residual at every gradient it gives."""

    def __init__(self, Op, b):
        super().__init__(Op=Op, b=b)
        self.history, self._norm = [], float(np.linalg.norm(b)) or 1.0

    def grad(self, x):
        r = self.Op.matvec(x) - self.b
        self.history.append(float(np.linalg.norm(r)) / self._norm)
        return self.Op.rmatvec(r)


def lipschitz_bound(op: EmissionOperator) -> float:
    """Upper bound of ``||A||^2`` (the gradient's Lipschitz constant of ``1/2 ||A x - y||^2``).

    Every entry of ``A`` is non-negative, so ``||A||_2^2 <= ||A||_1 ||A||_inf`` = (largest
    column sum) x (largest row sum) (Schur's test; Horn & Johnson, Matrix Analysis,
    5.6.P) from one ``A^T 1`` and one ``A 1``. On the paper's camera it is 1.2x the
    largest singular value squared found by power iteration, at a tenth of its cost.
    """
    return float(op.rmatvec(np.ones(op.shape[0])).max() * op.matvec(np.ones(op.shape[1])).max())


def check_views(views, op: EmissionOperator) -> np.ndarray:
    """Views as float64 of the operator's data shape, or a ValueError naming the problem."""
    v = np.asarray(views)
    if v.shape != tuple(op.dimsd):
        raise ValueError(f"views of shape {v.shape} do not come from this camera: its views are {tuple(op.dimsd)} "
                         "(N, N, n_rows, n_cols)")
    if not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"views must hold numbers. Received: dtype {v.dtype}")
    v = v.astype(np.float64)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"views contain {int(np.sum(~np.isfinite(v)))} NaN or infinite values")
    return v


def reconstruct(views, op: EmissionOperator, solver: str = DEFAULT_SOLVER, iters: int | None = None, *,
                damp: float = 0.0, tv: float = DEFAULT_TV, saturation: float | None = 1.0, progress: bool = False,
                callback=None) -> Reconstruction:
    """Recover the emission on the operator's planes from one light field.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`lf_flame.refocus.raw_to_views`), radiance units.
    op : EmissionOperator
        The camera and the planes (their depths and grids).
    solver : str
        One of :data:`SOLVERS`:

        - ``"adjoint"``: ``A^T y / A^T 1``, plain refocusing through the same rays (no iterations).
        - ``"lsqr"``: damped LSQR (Tikhonov, ``damp``), PyLops; may go negative.
        - ``"fista"``: accelerated proximal gradient on ``1/2 ||A x - y||^2`` with
          non-negativity (``pyproximal.Box(lower=0)``), step ``1 / L``
          (:func:`lipschitz_bound`); Beck & Teboulle, SIAM J. Imaging Sci. 2 (2009).
        - ``"pd-tv"``: PyProximal's primal-dual (Chambolle & Pock, J. Math. Imaging Vis.
          40 (2011)) on ``1/2 ||A x - y||^2 + tv sum ||grad x_k||`` (isotropic TV per
          plane) with ``x >= 0``.
        - ``"rl"``: Richardson-Lucy, ``x <- x A^T(y / A x) / A^T 1`` (the light-field
          microscopy default, 15 iterations; Broxton et al. 2013), non-negative.
    iters : int or None
        Iterations; None: :data:`DEFAULT_ITERS`.
    damp, tv : float
        LSQR's damping and the TV weight (>= 0); ignored by the other solvers.
    saturation : float or None
        The sensor's clipping level in the views' units (1.0: :func:`lf_flame.simulate.render`'s).
        A pixel at or above it holds only a lower bound of its light: the iterative solvers
        leave it out of the fit (weight 0 in ``||W (A x - y)||``; Richardson-Lucy: ratio
        left out). None: every pixel is fitted. The count is ``settings["n_saturated"]``.
    progress : bool
        A tqdm bar over the iterations.
    callback : callable or None
        ``callback(k, x)`` after iteration ``k`` (1-based) with the iterate ``x`` (flat,
        read-only use): error-against-iterations curves from one run.

    Returns
    -------
    Reconstruction

    Raises
    ------
    ValueError
        An unknown solver, negative iterations or weights, views of another camera
        (shape), NaN or inf in the views, a saturation level that is not positive.
    """
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}. Received: {solver!r}")
    iters = DEFAULT_ITERS[solver] if iters is None else int(iters)
    if iters < 0 or damp < 0 or tv < 0 or not (math.isfinite(damp) and math.isfinite(tv)):
        raise ValueError(f"iters, damp and tv must be finite and >= 0. Received: {iters}, {damp}, {tv}")
    if saturation is not None and not (math.isfinite(saturation) and saturation > 0):
        raise ValueError(f"saturation must be a positive finite level or None. Received: {saturation!r}")
    y = check_views(views, op).ravel()
    t0 = time.perf_counter()
    n = op.shape[1]
    fit = np.ones(y.size, bool) if saturation is None else y < saturation   # pixels that carry their light
    n_sat = int(y.size - fit.sum())
    # the fitted operator and data: W A and W y, W the 0/1 weight of the unsaturated pixels
    A, yw = (op, y) if n_sat == 0 else (pylops.Diagonal(fit.astype(np.float64)) @ op, np.where(fit, y, 0.0))
    settings = dict(iters=iters, rays_per_pixel=op.rays_per_pixel, seed=op.seed, saturation=saturation,
                    n_saturated=n_sat)
    bar = tqdm(total=iters, desc=f"reconstruct ({solver})", unit="it", disable=not progress)
    norm = float(np.linalg.norm(y)) or 1.0
    residuals = []
    count = [0]

    def step(x):
        count[0] += 1
        bar.update()
        if callback is not None:
            callback(count[0], np.ravel(x))
    if solver == "adjoint":
        x = op.normalised_adjoint(y.reshape(op.dimsd)).ravel()
        residuals = [float(np.linalg.norm(op.matvec(x) - y)) / norm]
    elif solver == "lsqr":
        settings["damp"] = damp
        out = lsqr(A, yw, np.zeros(n), damp=damp, niter=iters, calc_var=False, callback=step)
        x = np.ravel(out[0])
        residuals = np.asarray(out[-1])[1:] / norm   # LSQR's own ||A x - y|| estimate per iteration
    elif solver == "fista":
        settings["step"] = tau = 1.0 / lipschitz_bound(op)
        f = _TrackedL2(A, yw)
        x = ProximalGradient(f, pyproximal.Box(lower=0.0), np.zeros(n), tau=tau, niter=iters, acceleration="fista",
                             callback=step)
        residuals = f.history
    elif solver == "pd-tv":
        # the gradient block scaled by c to the norm of A (||c grad||^2 <= 8 c^2 = ||A||^2 bound):
        # with one step for both blocks, an unscaled TV term would move ~sqrt(||A||^2 / 8) times slower
        La = lipschitz_bound(op)
        c = math.sqrt(La / 8.0)
        grad = pylops.VStack([c * pylops.FirstDerivative(op.dims, axis=a, edge=True, kind="forward") for a in (1, 2)])
        K = pylops.VStack([A, grad])
        tau = mu = 0.99 / math.sqrt(2.0 * La)
        g = pyproximal.VStack([pyproximal.L2(b=yw), pyproximal.L21(ndim=2, sigma=tv / c)], nn=[op.shape[0], 2 * n])
        settings.update(tv=tv, step=tau)

        def track(xk):  # the primal-dual iteration exposes no residual: one more A, so only now and then
            k = count[0] + 1
            residuals.append(float(np.linalg.norm(A.matvec(xk) - yw)) / norm
                             if k == 1 or k % PD_RESIDUAL_EVERY == 0 or k == iters else math.nan)
            step(xk)
        x = PrimalDual(pyproximal.Box(lower=0.0), g, K, np.zeros(n), tau=tau, mu=mu, niter=iters, callback=track)
    else:  # rl
        ones = op.rmatvec(fit.astype(np.float64))
        seen = ones > 0
        yp = np.clip(yw, 0.0, None)
        x = np.full(n, max(float(yp[fit].mean()) if n_sat < y.size else 0.0, 1e-12))   # flat start, the data's level
        for _ in range(iters):
            ax = op.matvec(x)
            residuals.append(float(np.linalg.norm(np.where(fit, ax - y, 0.0))) / norm)
            ratio = np.where(fit, yp / np.maximum(ax, 1e-12), 0.0)
            x = np.where(seen, x * op.rmatvec(ratio) / np.where(seen, ones, 1.0), 0.0)
            step(x)
    bar.close()
    sample = tuple((h / op.dims[1], w / op.dims[2]) for h, w in op.sizes_mm)
    return Reconstruction(np.asarray(x).reshape(op.dims), op.depths_mm, sample, solver, settings,
                          np.asarray(residuals, np.float64), time.perf_counter() - t0)


# ---- scoring ---------------------------------------------------------------------------
def score_planes(planes, truth, camera: PlenopticCamera, depths_mm, objects=None, *, time_s=float("nan"),
                 measure=None, **labels):
    """The one scoring function of every route to the emission, per plane.

    Parameters
    ----------
    planes, truth : ndarray of shape (P, R, C)
        A route's planes (reconstructed, or refocused: the baseline) and the true emission
        on the same grid (:func:`scene_truth`), radiance units.
    camera : PlenopticCamera
    depths_mm : sequence of P float
    objects : sequence of P flame objects or None
        Each plane's flame (:func:`lf_flame.diagnostics.flame_truth`): its height is then
        measured on the plane (:func:`lf_flame.diagnostics.measure_flame`) and compared.
    time_s : float
        The route's wall time for the whole stack.
    measure : dict or None
        Keyword arguments of :func:`~lf_flame.diagnostics.measure_flame`: planes of emission
        are measured with :data:`~lf_flame.diagnostics.EMISSION_MEASURE`, refocused planes
        with the defaults (:func:`~lf_flame.diagnostics.measure_settings` of the route).
    **labels
        Columns added to every row (route, scene, noise ...).

    Returns
    -------
    DataFrame, one row per plane: labels, ``plane``, ``depth_mm``, ``rel_err`` (||x̂ − x|| /
    ||x||), ``ssim``, ``psnr_db`` (data range 1, :mod:`lf_flame.metrics`), and with
    objects ``height_mm``, ``height_mm_true``, ``height_err_mm``, ``flags`` (why a
    measurement is not to be trusted) and ``failure``; ``time_s``.
    """
    import pandas as pd

    from .diagnostics_scoring import score_stacks
    from .metrics import psnr_per_plane, ssim_per_plane
    planes, truth = np.asarray(planes, np.float64), np.asarray(truth, np.float64)
    if planes.shape != truth.shape or planes.ndim != 3 or len(depths_mm) != len(planes):
        raise ValueError(f"planes {planes.shape}, truth {truth.shape} and {len(depths_mm)} depths do not match")
    rel = np.linalg.norm((planes - truth).reshape(len(planes), -1), axis=1) / np.maximum(
        np.linalg.norm(truth.reshape(len(truth), -1), axis=1), 1e-300)
    df = pd.DataFrame(dict(labels, plane=range(len(planes)), depth_mm=[float(d) for d in depths_mm], rel_err=rel,
                           ssim=ssim_per_plane(truth, planes), psnr_db=psnr_per_plane(truth, planes)))
    if objects is not None:
        h = score_stacks(np.clip(planes, 0, None)[None], camera, [list(objects)], measure=measure)
        keep = [c for c in ("height_mm", "height_mm_true", "height_err_mm", "flags", "failure") if c in h]
        df = pd.concat([df, h[keep].reset_index(drop=True)], axis=1)
    df["time_s"] = time_s
    return df
