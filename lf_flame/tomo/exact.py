"""The camera's exact linear map, emission on planes -> views, as convolutions applied by FFT or by their taps.

:class:`~lf_flame.tomo.operator.EmissionOperator` is the renderer with a few fixed random
rays per pixel: a Monte-Carlo estimate of the camera. :class:`ExactOperator` is the map
the renderer estimates, computed from the same ray chain
(:func:`lf_flame.simulate.tracer.trace_coefficients`, the backward ABCD chain of
:func:`lf_flame.simulate.tracer.backward_chain`) by deterministic quadrature, with no ray
sampled at random.

The map's kernels and their quadrature, and why it is a convolution:
:mod:`lf_flame.tomo.quadrature`.

Samples off the views' grid (a colour capture's, each its nearest pixel): :class:`ExactOperator`'s
``sample_offsets``, each view as sub-views (:func:`offset_bins_for`).

Applied by FFT: ``x`` zero-padded to a canvas (``canvas_shape``) longer than the grid by
the largest kernel offset (no wrap-around reaches the views), SciPy's real 2-D FFTs
batched over planes and views, the per-frequency sum over planes (``A``) or views
(``A^T``, the conjugate kernels), and the inverse FFT cropped to the lenslet grid. The
adjoint is the exact transpose: the same kernels conjugated, padding and cropping swapped.
Where each view holds few taps (:data:`TAPS_FORWARD_MAX`, :data:`TAPS_ADJOINT_MAX`: planes near focus on the lenslet
grid) the same circular correlation on the canvas is summed over the taps directly (:mod:`lf_flame.tomo.taps`:
Numba, each view's kernel whole where the aperture clips it, else as a row filter after its column's filter), which
costs less than the views' FFTs there.

Precision: ``precision="float64"`` (the default) keeps the kernels' spectra complex128 and
the FFTs in float64: ``pylops.utils.dottest`` holds to 1e-12 and A^T is A's transpose to
float64 rounding, which the solvers' step sizes and the tests rely on. ``"float32"``
halves the FFTs' traffic and keeps the spectra in 16-bit fixed point, a quarter of float64's
memory (:class:`~lf_flame.tomo._fourier_kernels.PackedSpectra`: each view and plane's
real and imaginary parts scaled to their largest); A and A^T stay each other's transpose
to float32 rounding, and both are within 1-2e-5 of float64's, far below any data's noise
(a render's own error is 0.4 % at 400 rays per pixel), so it is for large stacks and the
solvers (``experiments/exact_operator.py`` measures both).
"""
from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.fft

from ..optics.camera import PlenopticCamera
from ..simulate.scenes import FLAME_EFFECTS
from ..simulate.layers import Effects
from . import _fourier_kernels
from .operator import PlanesOperator, normalised_adjoint
from .quadrature import QUADRATURE_NODES, ExactKernels, exact_kernels
from .taps import SEPARABLE_TOLERANCE, TapPlan, separable_taps

PRECISIONS = ("float64", "float32")
#: The most sub-views per view and axis of :class:`ExactOperator` for samples off the views' grid (a colour
#: capture's pixels, up to half a step away): each sample is then modelled within 1/6 of a step.
OFFSET_BINS = 3
#: How far (lenslets) a sample's view of a plane may lie from where its pixel sees it before the samples' offsets
#: are modelled (:func:`offset_bins_for`; a sample half a step off sees a plane of slope ``s`` ``|s| / 2`` lenslets
#: off). Chosen on the colour camera's validation captures (``experiments/cameras_colour.py --seed0 58100``, a
#: ``/tmp`` probe): at 0.1 the scene of two flames at -3.4 and -6.3 mm (slopes 0.11 and 0.20) ran on whole views,
#: its flames 6.4 -> 10.1 % and 4.0 -> 6.9 % (emission p90 8.8 -> 10.0 %); at 0.05 and 0.03 every figure was the
#: 3 sub-views'.
OFFSET_TOLERANCE = 0.05
#: :class:`ExactOperator` applies ``H`` (:meth:`ExactOperator.forward_canvas`) and ``H^H``
#: (:meth:`ExactOperator.adjoint_canvas`) on the canvas by direct sums over its taps instead of by FFT where its lit
#: views hold at most this many taps each (:attr:`ExactOperator.taps_per_view`, views whose kernels separate counted by
#: their row filters: :mod:`lf_flame.tomo.taps`). The taps' time grows with their count, the FFTs' with the views and
#: planes; measured on this project's 2-core machine (a ``/tmp`` probe of the paper camera's float32 operators, one and
#: two threads), the taps' time over the FFT route's: ``H`` 0.23-0.24 at 11.6 taps a view (2 planes, lenslet grid),
#: 0.46-0.51 at 30.0 (the paper's four planes), 0.58-0.61 at 41.5 (2 planes, 2 x 2 grid), 0.61-0.67 at 52.0 (8 planes),
#: 0.88-0.89 at 82.6 (planes at +-2 and +-6 mm, 2 x 2 grid), 1.07-1.17 at 104 (the paper's four planes, 2 x 2 grid);
#: ``H^H`` 0.26, 0.37-0.71, 0.71-0.90, 0.83, 0.98-1.11 and 1.28-1.36 at the same operators (the FFT route's adjoint
#: spares the views' inverse FFT: a forward FFT of the views is the cheaper of the two).
TAPS_FORWARD_MAX = 90
TAPS_ADJOINT_MAX = 64
#: ... and where the canvas is at least this many columns wide (the length of the taps' vectorised loops): on
#: narrower canvases the loops' ends and the taps' bookkeeping outweigh the products, and the FFTs of small views run
#: in cache. The paper's four planes on cameras of fewer lenslets (the same probe, one thread), the taps' time over
#: the FFT route's: canvas 36 x 27 ``H`` 1.46 and ``H^H`` 1.92, 60 x 45 1.62 and 2.05, 108 x 60 0.63 and 0.97,
#: 192 x 108 0.47 and 0.69 (decoded cameras of 10-48 px lenslet images ran their admm 1.2-2.1x slower by the taps).
TAPS_MIN_COLUMNS = 64


# ---- the operator ----------------------------------------------------------------------------
class ExactOperator(PlanesOperator):
    """The light field as a linear map of the emission on ``P`` planes, exact (no ray sampling).

    The map :class:`~lf_flame.tomo.operator.EmissionOperator` estimates with random rays,
    computed by quadrature of the same ray chain and applied as per-view convolutions
    by FFT (module docstring). Same ``dims``, ``dimsd``, planes and grids as
    ``EmissionOperator(camera, depths_mm, margin=margin, effects=effects)``, so every
    solver of :mod:`lf_flame.tomo.solvers` takes it.

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid (square, unrotated, integer pitch).
    depths_mm : sequence of float
        Depth offsets (mm from the focal plane, > 0 farther) of the ``P`` planes.
    margin : float
        Field-of-view factor of the planes' grids (:func:`~lf_flame.tomo.operator.plane_grid`);
        the grid has ``round(margin * n_rows) x round(margin * n_cols)`` samples, one per
        lenslet footprint, so ``margin * n_rows`` and ``margin * n_cols`` must be whole.
    effects : Effects
        Aperture and cos^4 as asked; occlusion and crosstalk must be off.
    precision : {"float64", "float32"}
        Of the kernels' spectra and the FFTs (module docstring). The interface is float64.
    quadrature_nodes : int
        Gauss-Legendre nodes per smooth piece of a pixel (:data:`~lf_flame.tomo.quadrature.QUADRATURE_NODES`).
    workers : int or None
        Threads of SciPy's FFTs and of the spectra's construction; None: all cores.
    subsamples : int
        Samples per lenslet footprint and axis of the planes' grids (default 1). Off focus
        the views see a plane at sub-lenslet shifts (their parallax), so a light field
        carries detail finer than a lenslet there; ``2`` models it (a 2 x 2 grid per lenslet,
        applied as ``4 P`` phase planes of the same convolutions: :func:`_phase_kernels`),
        at ``subsamples^2`` times the unknowns. At focus every view sees a sample's whole
        footprint, so there only the phases' sum is measured.
    sample_offsets : ndarray of shape (N, N, R, C, 2) or None
        Where each view sample's pixel lies from its view's place (view steps, along the
        views' rows and columns, within one step): a colour capture decoded pixel by pixel
        (:func:`lf_flame.real.view_grid.sample_offsets`), whose samples sit up to half a pixel
        from the grid of views. Each view is then modelled by ``offset_bins`` sub-views per
        axis, its pixel moved by ``(k + 1/2) / M - 1/2`` steps (``k < M``;
        :func:`~lf_flame.tomo.quadrature.exact_kernels`' ``view_shifts``), and each sample read from its nearest sub-view: the map stays a
        convolution per sub-view, at ``M^2`` times the views' cost. None: every sample at its
        view's place.
    offset_bins : int or None
        ``M``, sub-views per view and axis with ``sample_offsets``; None: as the planes need
        (:func:`offset_bins_for`, at most :data:`OFFSET_BINS`). 1: whole views (the offsets not modelled).

    Attributes
    ----------
    dims : (P, rows, cols)
        Model shape (plane as ``depths_mm``, rows down, columns right): ``subsamples``
        times the lenslet grid per axis.
    phase_dims : (P subsamples^2, rows / subsamples, cols / subsamples)
        The planes as the convolutions see them (:meth:`to_phases`).
    dimsd : (N, N, R, C)
        Data shape: the views of :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    offset_bins : int or None
        ``M`` where the samples' offsets are modelled (above 1), else None.
    view_dims : (N', N', R, C)
        The views the kernels are of: ``dimsd``, or with ``sample_offsets`` the ``N' = N M``
        sub-views per axis (:meth:`to_samples`, :meth:`from_samples`).
    kernels : ndarray of shape (N', N', P', Ty, Tx), float64
        The taps ``h`` of the ``P' = phase_dims[0]`` phase planes; tap ``(m, n)`` reads the
        phase plane at offset ``(tap_origin_y[u, k] + m, tap_origin_x[v, k] + n)`` lenslets
        from the pixel's lenslet.
    tap_origin_y, tap_origin_x : ndarray of shape (N', P'), int64
    weights : ndarray of shape (N', N', R, C), float64
        The per-pixel cos^4 drift ``w`` (1 without cos^4).
    canvas_shape : (int, int)
        The FFTs' size.
    nbytes : int
        Memory held: the kernels' spectra, the weights and the kernels.
    setup_s : float
        Wall time of ``__init__`` (quadrature, spectra), seconds.
    rays_per_pixel, seed : None
        No rays are sampled (for the solvers' records, which name the operator's sampling).

    Raises
    ------
    ValueError
        A non-perfect lenslet grid, occlusion or crosstalk on, no planes, a plane given twice, a plane
        at or nearer than the main lens's focal length (the camera cannot image it), a margin that does not give
        whole samples, an unknown precision, fewer than 1 quadrature node or subsample, or a camera whose chain is not
        shift-invariant across lenslets (message names the deviation); sample offsets of
        another shape than the views', not finite or more than a view step; fewer than 1 bin.

    Notes
    -----
    Measured on the paper's camera, 4 planes (shared 2-core machine, noisy; ``python
    experiments/exact_operator.py``, ``results/exact_operator.md``; the cost figures predate
    the lit-view spectra built by BLAS and the Numba sums, which lowered them: a float32
    setup of 0.7 s in ``results/fourier_solver_dense.csv``): setup 2.3 s (float64)
    / 1.8 s (float32), memory 217 / 123 MB (the spectra: ``N^2 P Lr (Lc/2 + 1)`` complex, now of the lit views only,
    numbers on a 200 x 108 canvas); one ``A`` 180 / 115 ms and one ``A^T`` 213 / 127 ms
    (medians), beside the 4-ray recorded Monte-Carlo operator's 133 and 127 ms, its record
    6.6 s and 251 MB. On a flame scene its light field differs from a 1,024-ray traced
    operator's by 0.22 / 0.23 / 0.16 / 0.39 % per plane (+20 / +10 / 0 / -10 mm), that
    operator's own seed-to-seed noise to within 1 %; the 4-ray operator's by 8.5-15 %.
    """

    def __init__(self, camera: PlenopticCamera, depths_mm, *, margin: float = 1.0, effects: Effects = FLAME_EFFECTS,
                 precision: str = "float64", quadrature_nodes: int = QUADRATURE_NODES, workers: int | None = None,
                 subsamples: int = 1, sample_offsets=None, offset_bins: int | None = None):
        t_start = time.perf_counter()
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}. Received: {precision!r}")
        self._gather, shifts, self.offset_bins = None, {}, None
        if sample_offsets is not None and offset_bins is None:
            offset_bins = offset_bins_for(camera, depths_mm)
        if sample_offsets is not None and offset_bins != 1:
            if isinstance(offset_bins, bool) or int(offset_bins) != offset_bins or offset_bins < 1:
                raise ValueError(f"offset_bins must be an integer >= 1. Received: {offset_bins!r}")
            self.offset_bins = int(offset_bins)
            shifts = dict(view_shifts=(np.arange(self.offset_bins) + 0.5) / self.offset_bins - 0.5)
        ek = self._kernels(camera, depths_mm, margin=margin, effects=effects, quadrature_nodes=quadrature_nodes,
                           subsamples=subsamples, **shifts)
        if sample_offsets is not None:                            # checked whether modelled or not
            self._gather = _offset_gather(ek.dimsd, sample_offsets, self.offset_bins or 1)
        h, weights, m0y, n0x = ek.kernels, ek.weights, ek.tap_origin_y, ek.tap_origin_x
        sub = ek.subsamples
        (N, _, R, C), (P, gr, gc), (n_ty, n_tx) = ek.dimsd, (h.shape[2], ek.dims[1] // sub, ek.dims[2] // sub), h.shape[3:]

        lr = scipy.fft.next_fast_len(max(gr - int(m0y.min()), R + int((m0y + n_ty - 1).max()), gr), real=True)
        lc = scipy.fft.next_fast_len(max(gc - int(n0x.min()), C + int((n0x + n_tx - 1).max()), gc), real=True)
        cdt = np.complex128 if precision == "float64" else np.complex64
        # the views with light: a view outside the aperture has no taps and no spectrum
        lit = np.flatnonzero(np.abs(h).reshape(N * N, -1).max(axis=1) > 0)
        # forward spectrum: conj(DFT of the taps placed at their offsets) = sum h e^{+2 pi i f m / L}
        fr = np.arange(lr)
        fc = np.arange(lc // 2 + 1)
        # phases from whole numbers modulo the canvas: exact whatever the offsets
        er = np.exp(2j * np.pi * ((fr[None, None, :, None] * (m0y[:, :, None, None] + np.arange(n_ty))) % lr) / lr)
        ec = np.exp(2j * np.pi * (((n0x[:, :, None, None] + np.arange(n_tx)[:, None]) * fc) % lc) / lc)
        self._real = np.float64 if precision == "float64" else np.float32
        # in the operator's precision (float32: complex64 products, 2.5e-7 of the largest entry from complex128's on
        # the 81-plane stack); one view per task on the workers' threads (BLAS releases the GIL): the spectra's
        # first touch of fresh memory, most of the time on one thread, is shared too
        er, ec, hr = er.astype(cdt), ec.astype(cdt), h.astype(self._real)
        shape = (len(lit), P, lr, lc // 2 + 1)
        spec = np.empty(shape, cdt) if precision == "float64" else _fourier_kernels.PackedSpectra(shape)
        workers = os.cpu_count() if workers is None else int(workers)

        store = spec.__setitem__ if precision == "float64" else spec.put

        def view_spectrum(i):                                     # (P, Lr, Ty) @ (P, Ty, Tx) @ (P, Tx, F), BLAS
            u, v = divmod(int(lit[i]), N)
            store(i, (er[u] @ hr[u, v]) @ ec[v])
        with ThreadPoolExecutor(max(1, workers)) as pool:
            list(pool.map(view_spectrum, range(len(lit))))
        self._spec, self._lit = spec, lit                             # (V', P, Lr, F): lit views only
        self._w = weights.reshape(N * N, R, C).astype(self._real)

        self.camera, self.effects, self.precision = camera, effects, precision
        self.quadrature_nodes = int(quadrature_nodes)
        self.depths_mm = ek.depths_mm
        self.sizes_mm = ek.sizes_mm
        self.centres_mm = ((0.0, 0.0),) * len(ek.depths_mm)
        self.margin = ek.margin
        self.rays_per_pixel = self.seed = None
        self.kernels, self.weights = h, weights
        self.tap_origin_y, self.tap_origin_x = m0y, n0x
        self.canvas_shape = (lr, lc)
        self.workers = workers
        self.subsamples, self.phase_dims = sub, (P, gr, gc)
        self.view_dims = (N, N, R, C)
        n = camera.pixels_per_lenslet
        super().__init__(ek.dims, (n, n, R, C))
        self.setup_s = time.perf_counter() - t_start

    #: What :meth:`binned` copies as it is (a subclass adds its own).
    _SHARED = ("camera", "effects", "precision", "quadrature_nodes", "depths_mm", "sizes_mm", "centres_mm", "margin",
               "rays_per_pixel", "seed", "weights", "canvas_shape", "workers", "_lit", "_real", "_w", "view_dims",
               "_gather", "offset_bins")

    @staticmethod
    def _kernels(camera, depths_mm, **kw) -> ExactKernels:
        """The map's kernels (:func:`~lf_flame.tomo.quadrature.exact_kernels`); a subclass on another lattice gives
        its own."""
        return exact_kernels(camera, depths_mm, **kw)

    def binned(self) -> "ExactOperator":
        """The same planes on the lenslet grid (``subsamples`` 1), from this operator's kernels.

        A plane that holds one value over each lenslet's ``s x s`` samples gives every phase
        image the same picture, so the lenslet grid's kernel of a plane is the sum of its
        ``s^2`` phase kernels (:func:`~lf_flame.tomo.quadrature._phase_kernels` read backwards), on the same taps and
        origins, and its spectra are the sums of theirs: the same optics and quadrature, no
        second quadrature (a few hundredths of a second against a new operator's setup).

        Returns
        -------
        ExactOperator
            ``self`` when ``subsamples`` is 1. Its ``setup_s`` is the binning's time.
        """
        s2 = self.subsamples ** 2
        if s2 == 1:
            return self
        t0 = time.perf_counter()
        new = object.__new__(type(self))
        for name in self._SHARED:
            setattr(new, name, getattr(self, name))
        (Pp, gr, gc), (N, _) = self.phase_dims, self.view_dims[:2]
        P = Pp // s2
        new.kernels = self.kernels.reshape((N, N, P, s2) + self.kernels.shape[3:]).sum(axis=3)
        new.tap_origin_y = np.ascontiguousarray(self.tap_origin_y[:, ::s2])   # the same for every phase
        new.tap_origin_x = np.ascontiguousarray(self.tap_origin_x[:, ::s2])
        new._spec = self._spec.binned(s2) if isinstance(self._spec, _fourier_kernels.PackedSpectra) else \
            self._spec.reshape((len(self._lit), P, s2) + self._spec.shape[2:]).sum(axis=2)
        new.subsamples, new.phase_dims = 1, (P, gr, gc)
        PlanesOperator.__init__(new, (P, gr, gc), self.dimsd)
        new.setup_s = time.perf_counter() - t0
        return new

    @property
    def nbytes(self) -> int:
        """Memory held: the kernels' spectra, the weights and the kernels."""
        return int(self._spec.nbytes + self._w.nbytes + self.kernels.nbytes + self.weights.nbytes)

    # ---- application -------------------------------------------------------------------
    def to_phases(self, x) -> np.ndarray:
        """Planes ``(P, s rows, s cols)`` as their phase images ``(P s^2, rows, cols)`` on the lenslet grid.

        Phase ``(a, b)`` of plane ``k`` is entry ``k s^2 + a s + b``: ``x[k, a::s, b::s]``
        (:func:`~lf_flame.tomo.quadrature._phase_kernels`). The identity (a view) when ``subsamples`` is 1.
        """
        s, (P, gr, gc) = self.subsamples, self.phase_dims
        x = np.reshape(x, self.dims)
        if s == 1:
            return x
        return x.reshape(-1, gr, s, gc, s).transpose(0, 2, 4, 1, 3).reshape(P, gr, gc)

    def from_phases(self, xp) -> np.ndarray:
        """The inverse of :meth:`to_phases`: phase images ``(P s^2, rows, cols)`` as planes ``self.dims``."""
        s, (P, gr, gc) = self.subsamples, self.phase_dims
        xp = np.reshape(xp, (P, gr, gc))
        if s == 1:
            return xp
        return xp.reshape(-1, s, s, gr, gc).transpose(0, 3, 1, 4, 2).reshape(self.dims)

    def to_samples(self, views) -> np.ndarray:
        """The data's samples ``dimsd`` read from views of ``view_dims`` (each sample from its
        sub-view with ``sample_offsets``; else the views as they are). Any dtype."""
        v = np.reshape(views, -1)
        return np.reshape(v if self._gather is None else v[self._gather], self.dimsd)

    def from_samples(self, samples, fill=0) -> np.ndarray:
        """The transpose of :meth:`to_samples`: data ``dimsd`` placed in views ``(N'^2, R, C)``, every
        sub-view sample that no data sample reads set to ``fill``."""
        a = np.asarray(samples)
        if self._gather is not None:
            v = np.full(int(np.prod(self.view_dims)), fill, a.dtype)
            v[self._gather] = a.ravel()
            a = v
        return a.reshape((-1,) + tuple(self.view_dims[2:]))

    def _by_taps(self, limit) -> bool:
        """Whether to sum over the taps rather than go through the FFT: at most ``limit`` taps a view on a canvas
        at least :data:`TAPS_MIN_COLUMNS` wide."""
        return self.canvas_shape[1] >= TAPS_MIN_COLUMNS and self.taps_per_view <= limit

    @property
    def taps_per_view(self) -> float:
        """Taps per lit view that :meth:`forward_canvas` and :meth:`adjoint_canvas` sum where they apply the map by
        its taps, the measure of :data:`TAPS_FORWARD_MAX` and :data:`TAPS_ADJOINT_MAX`: a view of taps that do not
        separate counts its taps (their rows in groups of four, a group counted whole where any of its taps is not
        zero, over the phase planes), a view whose taps separate counts its row filter's (the same groups), and each
        column's shared filter counts its taps once for the column (:func:`separable_taps`)."""
        return self._taps().per_view

    def _taps(self) -> TapPlan:
        """The lit views' taps as :func:`separable_taps` splits them, in the operator's precision; built once."""
        kept = self.__dict__.get("_taps_kept")
        if kept is None:
            u, v = np.divmod(np.asarray(self._lit, np.int64), self.kernels.shape[0])
            kept = self.__dict__["_taps_kept"] = separable_taps(
                self.kernels[u, v], self.tap_origin_y[u], self.tap_origin_x[v], v, self._real,
                SEPARABLE_TOLERANCE[np.dtype(self._real).name])
        return kept

    def forward_canvas(self, planes) -> np.ndarray:
        """``H`` on the canvas, without the crop and the cos^4 weights: phase planes to the lit views.

        The circular correlation of each plane with each view's taps on the canvas, summed over the planes: by
        direct sums over the taps where they are at most :data:`TAPS_FORWARD_MAX` a view on a canvas at least
        :data:`TAPS_MIN_COLUMNS` wide (:meth:`lf_flame.tomo.taps.TapPlan.forward`, threads of Numba), else by the
        planes' FFT, the per-frequency products with the spectra and the views' inverse FFT (``workers`` threads). Both
        give the same views to the spectra's precision (float32: their 16-bit fixed point, 1-2e-5 of the largest).

        Parameters
        ----------
        planes : ndarray of shape (P s^2, Lr, Lc)
            Real, on the canvas (``canvas_shape``); read in the operator's precision.

        Returns
        -------
        ndarray of shape (V', Lr, Lc), in the operator's precision
            The lit views (``_lit``) on the canvas.
        """
        x = np.ascontiguousarray(planes, self._real)
        if self._by_taps(TAPS_FORWARD_MAX):
            return self._taps().forward(x)
        return scipy.fft.irfft2(_fourier_kernels.spectra_forward(self._spec, scipy.fft.rfft2(x, workers=self.workers)),
                                s=self.canvas_shape, workers=self.workers)

    def adjoint_canvas(self, views) -> np.ndarray:
        """``H^H`` on the canvas, the transpose of :meth:`forward_canvas`: the lit views ``(V', Lr, Lc)``, or a window
        ``(V', R', C')`` of them from the canvas's first row and column (the rest 0), read in the operator's
        precision, to the phase planes ``(P s^2, Lr, Lc)``, in the operator's precision. By the taps where they are
        at most :data:`TAPS_ADJOINT_MAX` a view on a canvas at least :data:`TAPS_MIN_COLUMNS` wide, else by the
        views' FFT, the products with the conjugate spectra and the planes' inverse FFT."""
        z = np.ascontiguousarray(views, self._real)
        if self._by_taps(TAPS_ADJOINT_MAX):
            return self._adjoint_by_taps(z)
        return scipy.fft.irfft2(self._adjoint_by_spectra(z), s=self.canvas_shape, workers=self.workers)

    def adjoint_spectrum(self, views) -> np.ndarray:
        """The spectrum ``(P s^2, Lr, Lc // 2 + 1)`` of :meth:`adjoint_canvas` of the same views (what the
        per-frequency solves take): the products of the views' FFT with the conjugate spectra, or the FFT of the sums
        over the taps."""
        z = np.ascontiguousarray(views, self._real)
        if self._by_taps(TAPS_ADJOINT_MAX):
            return scipy.fft.rfft2(self._adjoint_by_taps(z), workers=self.workers)
        return self._adjoint_by_spectra(z)

    def _adjoint_by_taps(self, z) -> np.ndarray:
        """``H^H`` of the views ``z`` (the canvas or a window of it, the operator's precision) summed over the taps."""
        if z.shape[1:] != tuple(self.canvas_shape):
            z = np.pad(z, ((0, 0), (0, self.canvas_shape[0] - z.shape[1]), (0, self.canvas_shape[1] - z.shape[2])))
        return self._taps().adjoint(z)

    def _adjoint_by_spectra(self, z) -> np.ndarray:
        """The spectrum of ``H^H`` of the views ``z`` (the canvas or a window of it, zero-padded): their FFT times the
        conjugate spectra, summed over the views."""
        return _fourier_kernels.spectra_adjoint(self._spec, scipy.fft.rfft2(z, s=self.canvas_shape, workers=self.workers))

    def _matvec(self, x):
        N, _, R, C = self.view_dims
        planes = np.zeros((self.phase_dims[0],) + tuple(self.canvas_shape), self._real)
        planes[:, :self.phase_dims[1], :self.phase_dims[2]] = self.to_phases(x)
        y = np.zeros((N * N, R, C), self._real)
        y[self._lit] = self.forward_canvas(planes)[:, :R, :C]
        return self.to_samples(y * self._w).astype(np.float64, copy=False).ravel()

    def _rmatvec(self, y):
        P, gr, gc = self.phase_dims
        yw = self.from_samples(np.reshape(y, self.dimsd))[self._lit].astype(self._real, copy=False) * self._w[self._lit]
        return self.from_phases(self.adjoint_canvas(yw)[:, :gr, :gc]).astype(np.float64, copy=False).ravel()

    def normalised_adjoint(self, views) -> np.ndarray:
        """``A^T y / A^T 1``: each sample's weighted mean over the pixels that see it, a refocused stack.

        Parameters
        ----------
        views : ndarray of shape (N, N, R, C)

        Returns
        -------
        planes : ndarray of shape (P, rows, cols), float64; 0 where no pixel sees a sample.
        """
        return normalised_adjoint(self, views)


def offset_bins_for(camera: PlenopticCamera, depths_mm, cap: int = OFFSET_BINS) -> int:
    """The sub-views per view and axis that samples off the views' grid need on these planes: 1 or ``cap``.

    A sample whose pixel lies ``d`` view steps off its view's place (``|d|`` up to 1/2) sees a
    plane of slope ``s`` (lenslets per view step,
    :meth:`~lf_flame.optics.camera.PlenopticCamera.slope_for_depth`) ``|s| d`` lenslets off. Where
    that stays within :data:`OFFSET_TOLERANCE` on every plane (``max |s| / 2``: near focus) the
    whole views do (1), else ``cap``. No count between: with an even count no sub-view lies at the
    view's place, and for the emission 2 sub-views gave larger errors than 3 on 3 of 4 validation
    captures of the colour camera (flames at their true depths, a ``/tmp`` probe). The temperature
    route's cap of 2 was chosen with its own knobs
    (:data:`lf_flame.temperature.channels.DECODED_OFFSET_KNOBS`).

    Parameters
    ----------
    camera : PlenopticCamera
        The views' camera.
    depths_mm : sequence of float
        The planes (mm from the focus distance).
    cap : int

    Returns
    -------
    int
    """
    top = max(abs(camera.slope_for_depth(float(d))) for d in np.atleast_1d(depths_mm))
    return 1 if top / 2 <= OFFSET_TOLERANCE else int(cap)


def _offset_gather(view_dims, sample_offsets, M: int) -> np.ndarray | None:
    """Flat indices into the sub-views ``view_dims`` = (N M, N M, R, C) of each sample's nearest sub-view
    (:class:`ExactOperator`'s ``sample_offsets``), for the data (N, N, R, C) raveled; None for ``M`` 1 (whole
    views), the offsets checked either way."""
    N, R, C = view_dims[0] // M, view_dims[2], view_dims[3]
    off = np.asarray(sample_offsets, np.float64)
    if off.shape != (N, N, R, C, 2):
        raise ValueError(f"sample_offsets must be (N, N, R, C, 2) = {(N, N, R, C, 2)}, the views' shape and 2. "
                         f"Received: {off.shape}")
    if not np.all(np.isfinite(off)):
        raise ValueError("sample_offsets must be finite (NaN or inf found)")
    if np.abs(off).max() > 1.0:
        raise ValueError(f"sample_offsets must be within one view step of each view's place (largest "
                         f"{np.abs(off).max():.3g})")
    if M == 1:
        return None
    k = np.clip(np.floor((off + 0.5) * M), 0, M - 1).astype(np.int64)
    u = np.arange(N)[:, None, None, None] * M + k[..., 0]
    v = np.arange(N)[None, :, None, None] * M + k[..., 1]
    r, c = np.arange(R)[:, None], np.arange(C)[None, :]
    return (((u * (N * M) + v) * R + r) * C + c).ravel()


def emission_operator(camera: PlenopticCamera, depths_mm, *, rays_per_pixel: int | None = None,
                      effects: Effects = FLAME_EFFECTS, subsamples: int = 1, sample_offsets=None):
    """The camera's operator for ``depths_mm``: exact when it can be, traced when asked or needed.

    Parameters
    ----------
    camera : PlenopticCamera
    depths_mm : sequence of float
        Depth offsets (mm) of the planes.
    rays_per_pixel : int or None
        None: the :class:`ExactOperator` (float32: its rounding, ~1e-7, is far below any
        light field's noise) where the camera is a perfect lenslet grid and ``effects`` has no
        crosstalk, else the traced :class:`~lf_flame.tomo.operator.EmissionOperator` at 4 rays
        per pixel. A number: the traced operator at that many rays (the reference).
    effects : Effects
    subsamples : int
        The exact operator's samples per lenslet and axis (:class:`ExactOperator`); a
        traced operator keeps one per lenslet.
    sample_offsets : ndarray of shape (N, N, R, C, 2) or None
        Each sample's place off its view's (:class:`ExactOperator`; a light field's
        :attr:`~lf_flame.real.lightfield.LightField.sample_offsets`): the exact operator only.

    Returns
    -------
    ExactOperator or EmissionOperator

    Raises
    ------
    ValueError
        From the operator chosen (a plane the camera cannot image, no planes ...).
    """
    from .operator import EmissionOperator
    if rays_per_pixel is None and camera.perfect_grid and not effects.crosstalk and not effects.occlusion:
        return ExactOperator(camera, depths_mm, effects=effects, precision="float32", subsamples=subsamples,
                             sample_offsets=sample_offsets)
    if sample_offsets is not None:
        raise ValueError("samples off the views' grid (a colour capture's) are modelled by the exact operator only: "
                         "it needs a perfect lenslet grid and no crosstalk, and no rays_per_pixel")
    return EmissionOperator(camera, list(depths_mm), rays_per_pixel=4 if rays_per_pixel is None else int(rays_per_pixel),
                            effects=effects)
