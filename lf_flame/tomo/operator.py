"""The camera as a linear operator: emission on planes -> sub-aperture views.

With its ray samples fixed, the simulator's backward tracer
(:func:`lf_flame.simulate.tracer.render.render`, kernel
:func:`lf_flame.simulate._kernels.render_backward`) *is* the linear map ``A`` from the
emission on ``P`` planes to the views. :class:`EmissionOperator` wraps it and its exact
transpose (the same kernel scattering each pixel's value back to the texels its rays read)
as a :class:`PlanesOperator` (a SciPy ``LinearOperator`` with PyLops's ``dims`` and ``dimsd``). It
records its rays once (the same kernel writing each ray's weight and texels) and applies that record as a sparse matrix
(:mod:`lf_flame.tomo._kernels`): about twice as fast as tracing anew.

The grid of each plane (:func:`plane_grid`): one sample per lenslet footprint at the
plane's depth, ``p z / d`` mm (:func:`lf_flame.measure.diagnostics.lenslet_size_mm`), over
the lenslet grid's field of view there: the resolution a plenoptic 1.0 camera samples an
in-focus plane at, and the pixels of the refocused plane too.

Source: the paper's ray-transfer-matrix camera (Eq. 1, SPEC.md); projector and
back-projector from one geometry as in plenoptomos (Viganò et al., Opt. Express 2018).
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse.linalg

from ..optics.camera import PlenopticCamera
from ..optics.depth_range import check_planes_once
from ..refocus.shift_and_sum import _check_finite, raw_to_views, views_to_raw
from ..simulate import _kernels as _simulate_kernels
from ..simulate.scenes import FLAME_EFFECTS
from ..simulate.layers import Effects, Layer, Scene
from ..simulate.tracer import (
    NO_TABLE,
    _stack_layers,
    _validate_sampling,
    trace_coefficients,
)
from . import _kernels as _reconstruct_kernels

#: Parallel blocks of sensor rows of the adjoint, each scattering into its own buffer:
#: fixed, so the adjoint's sum is bit-identical at any thread count.
ADJOINT_BLOCKS = 8
#: Largest ray table (bytes: 4 per ray and plane for the texel, 4 per ray for the weight) an
#: :class:`EmissionOperator` records; a larger map is traced anew at every application.
#: The paper's camera, 4 planes, 4 rays per pixel: 292 MB.
RAY_TABLE_MAX_BYTES = 1 << 30


def plane_grid(camera: PlenopticCamera, depth_offset_mm: float, margin: float = 1.0):
    """Frame (height, width) in mm of the reconstruction grid of the plane at ``dz``.

    The grid has ``(n_rows, n_cols)`` samples (one per lenslet) over the lenslet grid's
    field of view at that depth (:meth:`~lf_flame.optics.camera.PlenopticCamera.field_of_view_mm`)
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


class PlanesOperator(scipy.sparse.linalg.LinearOperator):
    """A linear map from the emission on ``P`` planes to a light field's views, float64 at the interface.

    A :class:`scipy.sparse.linalg.LinearOperator` (``A @ x``, ``A.matvec``, ``A.rmatvec``,
    ``A.H``) that carries, as PyLops's operators do, the shapes of its model and its data:
    ``pylops.aslinearoperator(A)`` keeps them for PyLops's and PyProximal's solvers
    (:mod:`lf_flame.tomo.proximal`). SciPy's base rather than PyLops's keeps PyLops's import
    (SciPy's signal and stats modules, about a second) off every command that does not use it.

    Parameters
    ----------
    dims : (P, rows, cols)
        Model shape (axis order: plane, then rows down, columns right).
    dimsd : tuple of int
        Data shape, the views (N, N, R, C).
    """

    def __init__(self, dims, dimsd):
        self.dims, self.dimsd = tuple(int(d) for d in dims), tuple(int(d) for d in dimsd)
        super().__init__(np.float64, (math.prod(self.dimsd), math.prod(self.dims)))


class EmissionOperator(PlanesOperator):
    """The light field as a linear map of the emission on ``P`` planes.

    ``A x`` renders sub-aperture views of ``x`` with the simulator's backward tracer
    (the same kernel and the same rays as :func:`lf_flame.simulate.tracer.render`, noise-free,
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
        The renderer's ray samples (:func:`lf_flame.simulate.tracer.render`).
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
        Data shape: the views of :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    ray_table_bytes : int
        Size of the ray-by-ray record (texel indices and weights) before compression.

    Raises
    ------
    ValueError
        A non-perfect lenslet grid, no planes, a plane given twice, a plane at or nearer than the main
        lens's focal length (the camera cannot image it), a non-positive grid, occlusion on, bad sampling.

    Notes
    -----
    Traced (``ray_table=False``), one matvec costs one render of ``x`` (its content box
    culled, exactly) and one rmatvec the same rays again, scattering into
    :data:`ADJOINT_BLOCKS` buffers. Recorded, the tracer runs once, writing each ray's
    weight and texel indices (:mod:`lf_flame.tomo._kernels`); each application is
    then a gather or a scatter over that record, in float64.
    ``pylops.utils.dottest`` holds to float rounding (``tests/test_reconstruct.py``).
    """

    def __init__(self, camera: PlenopticCamera, depths_mm, *, grid_shape=None, sizes_mm=None, centres_mm=None,
                 margin: float = 1.0, effects: Effects = FLAME_EFFECTS, rays_per_pixel: int = 4, seed: int = 0,
                 ray_table: bool = True):
        if not camera.perfect_grid:
            raise ValueError("the emission operator needs a perfect lenslet grid (square, unrotated, integer "
                             "pitch); decode the capture to such views first (lf_flame.real.decoding)")
        if effects.occlusion:
            raise ValueError("occlusion makes the light field non-linear in the emission: flames are optically "
                             "thin, set Effects(occlusion=False)")
        depths = [float(d) for d in np.atleast_1d(np.asarray(depths_mm, dtype=np.float64))]
        if not depths:
            raise ValueError("depths_mm is empty: give at least one plane")
        check_planes_once(depths)     # two identical planes: the data cannot share their emission out
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
        super().__init__((len(depths), gr, gc), (n, n, camera.n_rows, camera.n_cols))
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
        """The map recorded ray by ray, as compressed rows (:mod:`lf_flame.tomo._kernels`),
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
        return normalised_adjoint(self, views)


def normalised_adjoint(op: PlanesOperator, views) -> np.ndarray:
    """``A^T y / A^T 1`` of any emission operator ``op``: each sample's weighted mean over
    the pixels that see it, a refocused stack (P, rows, cols), float64; 0 where no pixel
    sees a sample (``A^T 1`` at most 1e-12 of its largest value: an FFT's rounding)."""
    num = op.rmatvec(np.asarray(views, np.float64).ravel())
    den = op.rmatvec(np.ones(op.shape[0]))
    seen = den > 1e-12 * max(float(den.max()), 1e-300)
    return np.where(seen, num / np.where(seen, den, 1.0), 0.0).reshape(op.dims)


def check_views(views, op: EmissionOperator, keep_float32: bool = False) -> np.ndarray:
    """Views as float64 of the operator's data shape (read-only: the caller's own array where it is float64
    already, or float32 with ``keep_float32``: admm reads them once into its own buffers), or a ValueError
    naming the problem."""
    v = np.asarray(views)
    if v.shape != tuple(op.dimsd):
        raise ValueError(f"views of shape {v.shape} do not come from this camera: its views are {tuple(op.dimsd)} "
                         "(N, N, n_rows, n_cols)")
    if not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"views must hold numbers. Received: dtype {v.dtype}")
    try:
        _check_finite("views", v)
    except ValueError:
        raise ValueError(f"views contain {int(np.sum(~np.isfinite(v)))} NaN or infinite values") from None
    v = (v if keep_float32 and v.dtype == np.float32 else np.asarray(v, np.float64)).view()
    v.flags.writeable = False
    return v
