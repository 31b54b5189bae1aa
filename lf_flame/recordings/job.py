"""One recording's job: the settings a worker needs (its frames' decoding, planes, route and solver).

:mod:`lf_flame.recordings.chunk` processes a chunk of its frames.
"""
from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass, field

import numpy as np

from ..optics.camera import PlenopticCamera
from ..routes import parse_route
from ..simulate.scenes_time import FlameSequence
from .sources import SimulatedSource

#: Frames per Dask task: enough to make scheduling a small share of the work.
CHUNK = 16

#: This process's emission operator (with its ray record), kept across chunks and keyed by
#: what it is built from (camera, depths, rays per pixel): one per worker process, not one
#: per task. ``builds`` counts the operators this process built.
_OPERATOR = dict(key=None, op=None, builds=0)
_OPERATOR_LOCK = threading.Lock()


# ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class SequenceJob:
    """Everything a worker needs to process frames (pickled to it).

    Attributes
    ----------
    source : SimulatedSource, H5Source, TiffStackSource or FolderSource
    camera : PlenopticCamera
        The camera of the frames (lenslet grid, mm per lenslet of the diagnostics).
    fps : float
    depths_mm, slopes : tuple of float
        The planes: depth offsets (mm) and refocusing slopes (lenslets per view).
    columns : tuple of (int, int) or None per plane
        Column band of each plane's flame (lenslets); None: the whole plane.
    route : str
        ``"shift-sum"`` or ``"reconstruct-SOLVER"`` (:data:`lf_flame.tomo.solvers`).
    calibration : dict or None
        Real frames: ``GridCalibration.to_dict()``; decoded with ``white``/``dark`` into the views of
        ``camera``, which is then the decoded views' camera
        (:func:`lf_flame.real.own_camera.views_camera`), and solved as ``lf-flame reconstruct`` solves
        decoded views (:class:`lf_flame.tomo.lattice.LatticeOperator`, with decoding's interpolation;
        the data are the views times its white views, :func:`lf_flame.tomo.decoded.decoded_problem`); a
        hexagonal grid's on its own lattice, the planes resampled onto the square grid.
    white, dark : str or None
        Paths of the white image and dark frame (real frames).
    bin_views : int
        Real frames: pixels per view sample and axis they are decoded with (:func:`lf_flame.real.view_grid.auto_bin`).
    sensor : dict or None
        The frames of a colour camera: its sensor (``name``, ``pattern``, ``phase``;
        :func:`lf_flame.optics.colour.library_sensor`). Each frame is decoded with its channels apart
        (:func:`lf_flame.real.decoding.decode_colour`, one pixel per sample; on a perfect grid without a
        calibration each view sample is its pixel, of that pixel's channel) and levelled into one
        monochrome light field as ``lf-flame reconstruct`` levels a capture
        (:func:`lf_flame.temperature.mosaic.levelled_views`: the other channels' samples left out).
    truth_freqs_hz : tuple of float or None
        Simulated: plane ``k``'s flame's flicker frequency (Hz), within 0 to ``fps / 2``.
    chunk : int
        Frames per task (>= 1).
    iters : int or None
        ``reconstruct-*`` routes: the solver's iterations (>= 0); None: the solver's default
        (:data:`lf_flame.tomo.solvers.DEFAULT_ITERS`; admm: by the first frame's noise).
    tv : float or None
        ``reconstruct-pd-tv`` / ``-admm``: the TV weight (>= 0); None: the solver's default
        (admm: by the first frame's noise, :meth:`reconstruction`).
    saturation : float, "auto" or None
        ``reconstruct-*`` routes: the sensor's clipping level in the views' units (real frames: in
        the raw frames' units, the samples decoded from pixels at or above it,
        :func:`lf_flame.real.decoding.clipped_samples`); they are left out of the fit (their count
        per frame: ``n_saturated``). "auto": found in each frame
        (:func:`lf_flame.real.clipping.auto_saturation`: where its pixels pile up at its largest
        value, a frame that does not clip having no pile). None: every pixel is fitted.
    operator_rays : int or None
        ``reconstruct-*`` routes: rays per pixel of a traced emission operator (>= 1); None:
        the exact operator where the camera allows it
        (:func:`lf_flame.tomo.exact.emission_operator`).
    support : ndarray of bool of shape (P, R, C), or None
        ``reconstruct-admm``: where each plane may hold emission, on the lenslet grid of the planes
        (planes found in the first frame and near each other held to their own regions where they meet,
        as ``lf-flame reconstruct`` holds them: :func:`lf_flame.tomo.found_planes.found_support`); None:
        everywhere. A hexagonal grid's is taken to its lattice (:meth:`~lf_flame.tomo.lattice.LatticeOperator.from_square`).

    Raises
    ------
    ValueError
        ``chunk`` or ``bin_views`` below 1 or not whole, a frame rate not positive and finite, a true
        frequency outside 0 to ``fps / 2``, reconstruction settings out of range, a route
        other than shift-sum or reconstruct-SOLVER, ``operator_rays`` for real frames, a ``support``
        without admm or of another shape than (P, R, C).
    """

    source: object
    camera: PlenopticCamera
    fps: float
    depths_mm: tuple
    slopes: tuple
    columns: tuple
    route: str = "shift-sum"
    calibration: dict | None = None
    white: str | None = None
    dark: str | None = None
    truth_freqs_hz: tuple | None = None
    chunk: int = CHUNK
    iters: int | None = None
    tv: float | None = None
    saturation: float | str | None = "auto"
    operator_rays: int | None = None
    bin_views: int = 1
    sensor: dict | None = None
    support: np.ndarray | None = field(default=None, compare=False)
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        route = parse_route(self.route)
        if not route.tomographic and route != parse_route("shift-sum"):
            raise ValueError(f"a recording's route is shift-sum or reconstruct-SOLVER. Received: {self.route!r}")
        if isinstance(self.chunk, bool) or int(self.chunk) != self.chunk or self.chunk < 1:
            raise ValueError(f"chunk (frames per task) must be a whole number >= 1. Received: {self.chunk!r}")
        if not (math.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"the frame rate must be positive and finite (frames/s). Received: {self.fps!r}")
        for k, hz in enumerate(self.truth_freqs_hz or ()):
            if not (0 <= hz <= self.fps / 2):
                raise ValueError(f"flame {k}'s true frequency {hz:g} Hz lies outside the spectrum of "
                                 f"{self.fps:g} frames/s (0 to {self.fps / 2:g} Hz)")
        if self.iters is not None and (int(self.iters) != self.iters or self.iters < 0):
            raise ValueError(f"iters must be a whole number >= 0 or None. Received: {self.iters!r}")
        if self.tv is not None and not (math.isfinite(self.tv) and self.tv >= 0):
            raise ValueError(f"tv must be finite and >= 0. Received: {self.tv!r}")
        if self.saturation not in (None, "auto") and (isinstance(self.saturation, (str, bool)) or
                                                      not (math.isfinite(self.saturation) and self.saturation > 0)):
            raise ValueError(f"saturation must be a positive finite level, 'auto' or None. Received: "
                             f"{self.saturation!r}")
        if self.operator_rays is not None and (int(self.operator_rays) != self.operator_rays or self.operator_rays < 1):
            raise ValueError(f"operator_rays must be a whole number >= 1. Received: {self.operator_rays!r}")
        if isinstance(self.bin_views, bool) or int(self.bin_views) != self.bin_views or self.bin_views < 1:
            raise ValueError(f"bin_views must be a whole number >= 1. Received: {self.bin_views!r}")
        if self.sensor is not None and self.bin_views != 1:
            raise ValueError("a colour camera's frames are read one pixel per sample (bin_views 1)")
        if self.support is not None:
            shape = (len(self.depths_mm), self.camera.n_rows, self.camera.n_cols)
            if self.solver != "admm" or np.shape(self.support) != shape:
                raise ValueError(f"support holds admm's planes (P, R, C) = {shape} to regions. "
                                 f"Received: {np.shape(self.support)} for route {self.route!r}")
        if self.calibration is not None and self.operator_rays is not None:
            raise ValueError("operator_rays (--operator-rays) traces a simulated camera; real frames are solved on "
                             "their decoded views' exact operator")

    @property
    def n_chunks(self) -> int:
        return -(-self.source.n_frames // self.chunk)

    @property
    def solver(self) -> str | None:
        """The solver of a ``reconstruct-SOLVER`` route (:func:`lf_flame.routes.parse_route`);
        None for shift-and-sum."""
        route = parse_route(self.route)
        return route.solver if route.tomographic else None

    def reconstruction(self) -> dict | None:
        """The reconstruction's settings, defaults resolved (iterations of the solver's
        :data:`~lf_flame.tomo.defaults.DEFAULT_ITERS`, TV weight :data:`~lf_flame.tomo.defaults.DEFAULT_TV`
        for pd-tv, None for the solvers without one); None for shift-and-sum. admm's knobs
        not given are chosen once for the recording by its first frame's noise
        (:func:`lf_flame.tomo.noise_knobs.admm_knobs`; ``admm_noise``), so that every frame is
        solved alike; on an operator whose samples lie off the views' grid (a colour camera's) the fills
        cap and tolerance are :data:`~lf_flame.tomo.defaults.OFFSET_KNOBS`."""
        if self.solver is None:
            return None
        from ..tomo import defaults as D
        iters = D.DEFAULT_ITERS.get(self.solver) if self.iters is None else int(self.iters)
        tv = (D.DEFAULT_TV if self.solver == "pd-tv" else None) if self.tv is None else float(self.tv)
        out = dict(solver=self.solver, iters=iters, tv=tv,
                   saturation=self.saturation if self.saturation in (None, "auto") else float(self.saturation),
                   operator_rays=None if self.operator_rays is None else int(self.operator_rays))
        if self.solver == "admm":   # each chunk's frames after its first continue the previous frame's solve
            out["stream_fills"] = D.ADMM_STREAM_FILLS
        if self.solver == "admm" and (self.iters is None or self.tv is None):
            key = ("admm", self.iters, self.tv, self.saturation)
            if key not in self._cache:
                from ..tomo.noise_knobs import admm_knobs
                data, leave = self.fit_data(*self.frame(np.asarray(next(iter(self.source.frames(0, 1))), np.float64)))
                fit = None if leave is None else ~leave if np.ndim(leave) else data < leave
                self._cache[key] = admm_knobs(data, fit, self.iters, self.tv)
            knobs = dict(self._cache[key])
            out.update(iters=knobs.pop("fills"), admm_noise=knobs.pop("noise"), **knobs)
            if self.iters is None and self.calibration is not None and self.operator().offset_bins is not None:
                out.update(iters=D.OFFSET_KNOBS["fills"], tol=D.OFFSET_KNOBS["tol"])   # sub-views: slower fills
        return out

    def identity(self) -> dict:
        """What makes the run: a folder holding another identity is not resumed."""
        out = dict(source=self.source.identity(), camera=self.camera.to_json(), fps=self.fps,
                   depths_mm=list(self.depths_mm), slopes=list(self.slopes),
                   columns=[None if c is None else list(c) for c in self.columns], route=self.route,
                   calibration=self.calibration, white=self.white, dark=self.dark, chunk=self.chunk,
                   bin_views=self.bin_views, sensor=self.sensor, reconstruction=self.reconstruction())
        if self.support is not None:         # its digest (the planes' regions)
            out["support_sha256"] = hashlib.sha256(np.packbits(np.asarray(self.support, bool))).hexdigest()
        return out

    @property
    def hexagonal(self) -> bool:
        """Real frames of a hexagonal lenslet grid: solved on its own lattice (:mod:`lf_flame.tomo.lattice`)."""
        return self.calibration is not None and self.calibration.get("layout") == "hex"

    def views(self, raw: np.ndarray) -> np.ndarray:
        """Sub-aperture views (N, N, R, C) of one raw frame (decoded when real; a hexagonal grid's
        resampled onto the square grid of ``camera``)."""
        views = self.frame(raw)[0]
        return self._square(views)

    def _square(self, views):
        """A hexagonal grid's lattice views on the square grid (:func:`lf_flame.real.view_grid.on_square_grid`)."""
        if not self.hexagonal:
            return views
        from ..real.view_grid import on_square_grid
        return on_square_grid(views, self._cache["cal"])

    def frame(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """One raw frame's views (N, N, R, C; decoded when real, a hexagonal grid's on its own lattice)
        and the samples to leave out of the fit: for real frames those decoded from pixels at or above
        ``saturation``, for simulated ones none (None: the level does it); with the sensor's defective pixels
        (:mod:`lf_flame.real.defects`: found in the first frame this job reads, a sensor's defects being the
        same in every frame, and repaired in each)."""
        from ..refocus.shift_and_sum import raw_to_views
        if not np.all(np.isfinite(raw)):
            raise ValueError(NONFINITE_FRAME)
        if self.calibration is None:
            from ..real.defects import capture_defects, grid_offsets
            if raw.shape != tuple(self.camera.sensor_shape):
                raise ValueError(f"frame of {raw.shape[0]} x {raw.shape[1]} pixels; the camera's sensor is "
                                 f"{self.camera.sensor_shape[0]} x {self.camera.sensor_shape[1]}")
            n = self.camera.pixels_per_lenslet
            off = grid_offsets(n, colour=self.sensor is not None)
            bad = self._defect_map(raw, off)
            if not bad.any():                           # nothing to repair: the frame as it is
                views, left = raw_to_views(raw, n), None
            else:
                fixed = capture_defects(raw, off, flagged=bad)[1]
                views, left = raw_to_views(fixed.astype(np.float32), n), raw_to_views(bad, n) > 0.5
            if self.sensor is None:
                return views, left
            # a colour mosaic on a perfect grid: each sample its pixel's channel, levelled as a decoded colour
            # frame is (lf_flame.temperature.mosaic.monochrome_light_field), its clipped pixels left out first
            from ..temperature.mosaic import levelled_views
            if "channels" not in self._cache:
                self._cache["channels"] = raw_to_views(self._sensor().channel_map(raw.shape).astype(np.float32),
                                                       n).astype(np.int8)
            level = self._level(views)
            clipped = None if level is None else views >= level
            views, other, _ = levelled_views(views, self._cache["channels"])
            self._cache["other_channels"] = other
            for m in (left, clipped):
                other = other if m is None else other | m
            return views, other
        from ..real.decoding import decode_repaired
        from ..real.view_grid import views_shape
        c = self._decoding()
        if raw.shape != tuple(c["cal"].sensor_shape):
            raise ValueError(f"frame of {raw.shape[0]} x {raw.shape[1]} pixels; the calibration's sensor is "
                             f"{c['cal'].sensor_shape[0]} x {c['cal'].sensor_shape[1]}")
        n, k = self.camera.pixels_per_lenslet, self.bin_views
        grid = views_shape(c["cal"], n, k)[2:]
        if grid != (self.camera.n_rows, self.camera.n_cols):
            raise ValueError(f"decoded views of {grid[0]} x {grid[1]} lenslets; the camera has "
                             f"{self.camera.n_rows} x {self.camera.n_cols} (give the decoded views' camera)")
        from ..real.defects import grid_offsets
        defects = self._defect_map(raw, grid_offsets(c["cal"], c["sensor"] is not None), c["dark"])
        # the grid is checked in the first frame this job decodes (33 ms of a 1080 x 1080 frame): one camera's
        # recording shows the same grid in every frame, as it holds the same defects; the white image is sampled
        # once, for every frame
        white, white_views = c["white"], None
        if white is not None:
            if "white_views" not in self._cache:
                from ..real.decoding import white_samples
                self._cache["white_views"] = white_samples(c["cal"], white, c["dark"], n_views=n, bin_views=k,
                                                           sensor=c["sensor"])
            white, white_views = None, self._cache["white_views"]
        views, channels, _, clipped, _ = decode_repaired(raw, c["cal"], white, c["dark"], c["sensor"],
                                                         self._level(raw), n_views=n, bin_views=k, defects=defects,
                                                         check="grid_checked" not in self._cache,
                                                         white_views=white_views)
        self._cache["grid_checked"] = True
        if channels is None:
            return views, clipped
        from ..temperature.mosaic import levelled_views
        views, other, _ = levelled_views(views, channels)
        self._cache["other_channels"] = other
        return views, other if clipped is None else other | clipped

    def _sensor(self):
        """The colour sensor (:func:`lf_flame.optics.colour.library_sensor`) of ``sensor``, or None."""
        if self.sensor is None:
            return None
        from ..optics.colour import library_sensor
        return library_sensor(self.sensor["name"], self.sensor["pattern"], tuple(self.sensor["phase"]))

    def _decoding(self) -> dict:
        """What decodes each real frame, read once: the grid calibration (``cal``), the ``white`` and ``dark``
        images (or None) and the colour ``sensor`` (or None)."""
        if "cal" not in self._cache:
            from ..real.calibration import GridCalibration
            from ..real.images import decoding_images
            white, dark = decoding_images(self.white, self.dark)                  # in the frames' units
            self._cache.update(cal=GridCalibration.from_dict(self.calibration), white=white, dark=dark,
                               sensor=self._sensor())
        return self._cache

    def unlit_level(self, raw: np.ndarray) -> float | None:
        """What a real frame reads where its white image is dark (:func:`lf_flame.real.black_level.unlit_level`,
        the dark frame subtracted): about 0 unless a black level or stray light is left in; None for a simulated
        recording's frames or without a white image."""
        if self.calibration is None:
            return None
        from ..real.black_level import unlit_level
        c = self._decoding()
        return unlit_level(raw, c["white"], c["dark"])

    def unit(self, raw: np.ndarray) -> float:
        """One raw frame's unit for the solvers (:func:`lf_flame.tomo.solvers.reconstruct`'s ``unit``): its clipping
        level (:meth:`_level`), 1 where it has none; a colour camera's decoded views keep the raw frame's units, a
        monochrome camera's decoded with a white image are relative to it: 1 (as
        :attr:`lf_flame.real.lightfield.LightField.unit`)."""
        if self.calibration is not None and self.white is not None and self.sensor is None:
            return 1.0
        level = self._level(raw)
        return 1.0 if level is None else float(level)

    def _level(self, image) -> float | None:
        """The clipping level of one frame (its raw image or views): ``saturation``, found in the frame where "auto"."""
        if self.saturation != "auto":
            return self.saturation
        from ..real.clipping import found_level
        return found_level(image)

    def clipped_share(self, raw: np.ndarray) -> float:
        """One raw frame's clipped pixels' share of its lit ones, at the frame's level (:meth:`_level`;
        :func:`lf_flame.real.clipping.clipped_share`)."""
        from ..real.clipping import clipped_share
        return clipped_share(raw, self._level(raw))

    def _defect_map(self, raw, offsets, dark=None) -> np.ndarray:
        """The sensor's defective pixels (:func:`lf_flame.real.defects.capture_defects`), found once per job in the
        recording's first frame, so that every chunk and worker repairs the same pixels in every frame (in ``raw``
        for a job without a source)."""
        if "defects" not in self._cache:
            from ..real.defects import capture_defects
            first = raw if self.source is None else np.asarray(next(iter(self.source.frames(0, 1))), np.float64)
            if first.shape != raw.shape:
                raise ValueError(f"the recording's first frame is {first.shape[0]} x {first.shape[1]} pixels, this "
                                 f"one {raw.shape[0]} x {raw.shape[1]}")
            self._cache["defects"] = capture_defects(first, offsets, dark=dark)[0]
        return self._cache["defects"]

    def fit_data(self, views: np.ndarray, clipped=None):
        """A frame's data for the ``reconstruct-*`` routes and what to leave out of the fit (:meth:`frame`'s
        views and clipped samples): simulated views as they are with the clipping level (and their defective
        pixels' samples); decoded views times the operator's white views with the clipped and dark samples
        (:func:`lf_flame.tomo.decoded.decoded_problem`; a hexagonal lattice's in axial storage, its empty
        corners left out too, :func:`lf_flame.tomo.lattice.to_axial`)."""
        if self.calibration is None:
            if self.sensor is not None:                 # levelled colour views: clipped pixels already out
                return views, clipped
            level = self._level(views)
            if clipped is None or level is None:
                return views, level if clipped is None else clipped
            return views, clipped | (views >= level)
        from ..tomo.decoded import decoded_problem
        op = self.operator()
        if not self.hexagonal:
            return decoded_problem(views, op, clipped)
        from ..tomo.lattice import to_axial
        data, leave = decoded_problem(to_axial(views)[0], op, None if clipped is None else to_axial(clipped)[0])
        return data, leave | ~op.inside

    def planes(self, views: np.ndarray) -> np.ndarray:
        """The focal stack (P, R, C) of one frame, by the job's route."""
        return self.planes_and_saturated(views)[0]

    def planes_and_saturated(self, views: np.ndarray, state: dict | None = None,
                             clipped: np.ndarray | None = None,
                             unit: float | None = None) -> tuple[np.ndarray, int | None]:
        """The focal stack (P, R, C) of one frame by the job's route, and the count of its
        pixels left out of the fit as saturated (``reconstruct-*``; None for shift-and-sum).

        ``state`` (admm): the solve carried from the previous frame of the chunk
        (:func:`lf_flame.tomo.fourier.solve_admm`): empty for a chunk's first frame (solved
        from scratch), then at most ``stream_fills`` fills per frame
        (:data:`~lf_flame.tomo.defaults.ADMM_STREAM_FILLS`); a frame whose total light differs from the
        previous frame's by more than :data:`~lf_flame.tomo.defaults.ADMM_STREAM_LIGHT` is solved from scratch.
        ``clipped``: a real frame's samples from clipped pixels (:meth:`frame`); ``unit``: the frame's clipping level
        (:meth:`unit`), the solvers' unit where the fit is a mask (decoded frames, defective pixels), as
        :func:`lf_flame.tomo.solvers.reconstruct`'s. A frame without light (no sample
        fitted above 0) has empty planes, unsolved (lsqr's had been NaN)."""
        if self.solver is None:
            from ..refocus.shift_and_sum import aperture_mask, focal_stack
            n = views.shape[0]
            return focal_stack(self._square(views), self.slopes, aperture_mask(n, "circular")), None
        from ..tomo.solvers import reconstruct
        from ..tomo.defaults import ADMM_STREAM_LIGHT
        r = self.reconstruction()
        data, leave = self.fit_data(views, clipped)
        light = float(np.sum(data, dtype=np.float64))
        prev = state.get("light", 0.0) if state else 0.0
        if state and not (prev > 0 and prev / ADMM_STREAM_LIGHT <= light <= prev * ADMM_STREAM_LIGHT):
            state.clear()                   # unlike the previous frame: its solve is no start for this one
        iters = min(r["iters"], r["stream_fills"]) if state else r["iters"]
        from ..tomo.solvers import fitted_pixels
        fitted = fitted_pixels(data, leave)
        if fitted.any() and not np.any(data[fitted] > 0):   # no light: no emission (lsqr had divided 0 by 0: NaN)
            if state is not None:
                state.clear()
            planes = np.zeros(tuple(self.operator().dims))
            if self.hexagonal:
                planes = self.operator().to_square(planes, self.camera.n_rows, self.camera.n_cols)
            return planes, self._saturated(fitted, int(np.count_nonzero(~fitted)))
        rec = reconstruct(data, self.operator(), r["solver"], iters, tv=r["tv"], lam=r.get("lam"), l1=r.get("l1"),
                          start=r.get("start"), tol=r.get("tol"), saturation=leave, unit=unit,
                          state=state if r["solver"] == "admm" else None,
                          **({} if self.support is None else dict(support=self._support())))
        if state is not None and r["solver"] == "admm":
            state["light"] = light
        planes = self.operator().to_square(rec.planes, self.camera.n_rows, self.camera.n_cols) if self.hexagonal \
            else rec.planes
        return planes, self._saturated(fitted, int(rec.settings["n_saturated"]))

    def _saturated(self, fitted: np.ndarray, left_out: int) -> int:
        """The frame's samples left out of the fit (``left_out``: a hexagonal lattice's of its cells with a lenslet),
        less a colour frame's other channels' (:func:`lf_flame.temperature.mosaic.levelled_views`: its blue samples,
        left out of every frame, are no saturated pixels; they had been counted as such, every blue sample in
        every frame)."""
        other = self._cache.get("other_channels")
        if other is None or np.shape(other) != np.shape(fitted):
            return left_out
        return int(np.count_nonzero(~fitted & ~other))

    def _support(self) -> np.ndarray:
        """``support`` on the operator's planes: a hexagonal grid's taken to its lattice."""
        return self.operator().from_square(self.support) if self.hexagonal else self.support

    def operator(self):
        """The emission operator of the planes (:func:`lf_flame.tomo.exact.emission_operator`:
        exact, or traced at ``operator_rays`` rays per pixel; real frames: the decoded views'
        :class:`~lf_flame.tomo.lattice.LatticeOperator` with decoding's interpolation, a colour camera's with
        each sample at its own pixel, :func:`lf_flame.real.view_grid.sample_offsets`), built once per
        process and kept (with its spectra or ray record) while the camera, depths, rays and
        calibration stay."""
        from ..tomo.exact import emission_operator
        if "operator_key" not in self._cache:       # once per job: the calibration's JSON lists every lenslet
            import json
            self._cache["operator_key"] = (self.camera.to_json(), tuple(float(d) for d in self.depths_mm),
                                           self.operator_rays, json.dumps(self.calibration, sort_keys=True),
                                           self.bin_views, self.sensor is None)
        key = self._cache["operator_key"]
        with _OPERATOR_LOCK:
            if _OPERATOR["key"] != key:
                _OPERATOR.update(key=None, op=None)   # the old one's memory goes first
                if self.calibration is not None:
                    from ..real.calibration import GridCalibration
                    from ..real.view_grid import interpolation_phases
                    from ..tomo.lattice import LatticeOperator
                    from ..real.view_grid import sample_offsets
                    cam, k, cal = self.camera, self.bin_views, GridCalibration.from_dict(self.calibration)
                    colour = self.sensor is not None                 # nearest pixels, each at its own place
                    interpolation = None if colour else (interpolation_phases(cal, cam.pixels_per_lenslet, k), k)
                    op = LatticeOperator(cam, list(self.depths_mm), (cal.n_rows, cal.n_cols), layout=cal.layout,
                                         interpolation=interpolation,
                                         sample_offsets=sample_offsets(cal, cam.pixels_per_lenslet) if colour else None)
                else:
                    op = emission_operator(self.camera, list(self.depths_mm), rays_per_pixel=self.operator_rays)
                _OPERATOR.update(key=key, op=op, builds=_OPERATOR["builds"] + 1)
            return _OPERATOR["op"]


def simulated_job(seq: FlameSequence, camera: PlenopticCamera, source=None, *, route: str = "shift-sum",
                  chunk: int = CHUNK, slopes=None, **reconstruction) -> tuple[SequenceJob, np.ndarray]:
    """The job of a simulated recording, one plane per flame at its depth, and its truth.

    Each plane's diagnostics look in its flame's column band (the first frame's ``roi``
    widened by 2 lenslets, which holds the sway); its true frequency is the flame's.

    Parameters
    ----------
    seq : FlameSequence
    camera : PlenopticCamera
    source : frame source or None
        The frames (e.g. an HDF5 stack written by :func:`write_frames`); None: rendered
        in the workers (:class:`SimulatedSource`, 4 rays per pixel).
    route, chunk : as :class:`SequenceJob`
    slopes : sequence of float or None
        One per flame; None: the camera's analytic slopes of the flames' depths.
    **reconstruction
        ``iters``, ``tv``, ``saturation``, ``operator_rays`` of :class:`SequenceJob`.

    Returns
    -------
    (job, truth) : truth of shape (T, P), each flame's true height (mm) per frame.
    """
    depths = tuple(f.depth_offset_mm for f in seq.flames)
    cols = tuple((max(0, o["roi"][2] - 2), min(camera.n_cols, o["roi"][3] + 2))
                 for o in seq.scene(camera, 0).objects)
    slopes = tuple(camera.slope_for_depth(d) for d in depths) if slopes is None else tuple(slopes)
    freqs, heights = sequence_truth(seq)
    job = SequenceJob(source or SimulatedSource(seq, camera, 4), camera, seq.fps, depths, slopes, cols, route,
                      truth_freqs_hz=freqs, chunk=chunk, **reconstruction)
    return job, heights


def sequence_truth(seq) -> tuple:
    """A simulated recording's truth for planes at its flames' depths (plane ``k`` flame ``k``'s): each flame's
    flicker frequency (Hz) and its true height (mm) per frame, (T, P)."""
    return tuple(f.freq_hz for f in seq.flames), np.array([seq.heights_mm(i) for i in range(seq.n_frames)])


#: The failure of every plane of a frame that holds NaN or inf (:func:`lf_flame.recordings.chunk.process_chunk`).
NONFINITE_FRAME = "frame holds NaN or inf"
