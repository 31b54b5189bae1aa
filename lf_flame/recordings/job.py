"""One recording's job: the settings a worker needs, and the processing of one chunk.

Every frame is refocused at the planes (or reconstructed, :mod:`lf_flame.tomo`) and
measured per plane by :func:`lf_flame.measure.diagnostics.measure_flame`.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..optics.camera import PlenopticCamera
from ..routes import parse_route
from ..simulate.scenes_time import FlameSequence
from .sources import SimulatedSource

#: Frames per Dask task: enough to make scheduling a small share of the work.
CHUNK = 16


# ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class SequenceJob:
    """Everything a worker needs to process frames (pickled to it).

    Attributes
    ----------
    source : SimulatedSource, H5Source or FolderSource
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
        Real frames: ``GridCalibration.to_dict()``; decoded with ``white``/``dark``.
    white, dark : str or None
        Paths of the white image and dark frame (real frames).
    truth : tuple of tuple of float, or None
        Simulated: the true height (mm) of plane ``k``'s flame, per frame.
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
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n_chunks(self) -> int:
        return -(-self.source.n_frames // self.chunk)

    def identity(self) -> dict:
        """What makes the run: a folder holding another identity is not resumed."""
        return dict(source=self.source.identity(), camera=self.camera.to_json(), fps=self.fps,
                    depths_mm=list(self.depths_mm), slopes=list(self.slopes),
                    columns=[None if c is None else list(c) for c in self.columns], route=self.route,
                    calibration=self.calibration, white=self.white, dark=self.dark, chunk=self.chunk)

    def views(self, raw: np.ndarray) -> np.ndarray:
        """Sub-aperture views (N, N, R, C) of one raw frame (decoded when real)."""
        from ..refocus.shift_and_sum import raw_to_views
        if not np.all(np.isfinite(raw)):
            raise ValueError("frame holds NaN or inf")
        if self.calibration is None:
            if raw.shape != tuple(self.camera.sensor_shape):
                raise ValueError(f"frame of {raw.shape[0]} x {raw.shape[1]} pixels; the camera's sensor is "
                                 f"{self.camera.sensor_shape[0]} x {self.camera.sensor_shape[1]}")
            return raw_to_views(raw, self.camera.pixels_per_lenslet)
        from ..real.calibration import GridCalibration, load_image
        from ..real.decoding import decode
        if "cal" not in self._cache:
            self._cache.update(cal=GridCalibration.from_dict(self.calibration),
                               white=None if self.white is None else load_image(self.white),
                               dark=None if self.dark is None else load_image(self.dark))
        c = self._cache
        if raw.shape != tuple(c["cal"].sensor_shape):
            raise ValueError(f"frame of {raw.shape[0]} x {raw.shape[1]} pixels; the calibration's sensor is "
                             f"{c['cal'].sensor_shape[0]} x {c['cal'].sensor_shape[1]}")
        views = decode(raw, c["cal"], c["white"], c["dark"], n_views=self.camera.pixels_per_lenslet)
        if views.shape[2:] != (self.camera.n_rows, self.camera.n_cols):
            raise ValueError(f"decoded views of {views.shape[2]} x {views.shape[3]} lenslets; the camera has "
                             f"{self.camera.n_rows} x {self.camera.n_cols} (give the capture's camera)")
        return views

    def planes(self, views: np.ndarray) -> np.ndarray:
        """The focal stack (P, R, C) of one frame, by the job's route."""
        route = parse_route(self.route)
        if not route.tomographic and route != parse_route("shift-sum"):
            raise ValueError(f"a recording's route is shift-sum or reconstruct-SOLVER. Received: {self.route!r}")
        if not route.tomographic:
            from ..refocus.shift_and_sum import aperture_mask, focal_stack
            n = views.shape[0]
            return focal_stack(views, self.slopes, aperture_mask(n, "circular"))
        from ..tomo.operator import EmissionOperator
        from ..tomo.solvers import reconstruct
        if "op" not in self._cache:
            self._cache["op"] = EmissionOperator(self.camera, list(self.depths_mm), rays_per_pixel=4)
        return reconstruct(views, self._cache["op"], route.solver).planes


def simulated_job(seq: FlameSequence, camera: PlenopticCamera, source=None, *, route: str = "shift-sum",
                  chunk: int = CHUNK, slopes=None) -> tuple[SequenceJob, np.ndarray]:
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

    Returns
    -------
    (job, truth) : truth of shape (T, P), each flame's true height (mm) per frame.
    """
    depths = tuple(f.depth_offset_mm for f in seq.flames)
    cols = tuple((max(0, o["roi"][2] - 2), min(camera.n_cols, o["roi"][3] + 2))
                 for o in seq.scene(camera, 0).objects)
    slopes = tuple(camera.slope_for_depth(d) for d in depths) if slopes is None else tuple(slopes)
    job = SequenceJob(source or SimulatedSource(seq, camera, 4), camera, seq.fps, depths, slopes, cols, route,
                      truth_freqs_hz=tuple(f.freq_hz for f in seq.flames), chunk=chunk)
    return job, np.array([seq.heights_mm(i) for i in range(seq.n_frames)])


def _warm_up(job: SequenceJob) -> None:
    """Process frame 0 once (imports, Numba's kernels loaded): a worker's first task then
    costs what every other does."""
    process_chunk(0, dataclasses.replace(job, chunk=1))


def process_chunk(c: int, job: SequenceJob) -> dict:
    """Process chunk ``c`` of ``job`` (frames ``c * chunk`` to ``(c + 1) * chunk``).

    Returns
    -------
    dict with ``rows`` (one dict per frame and plane: frame, time_s, plane, depth_mm,
    :meth:`FlameMeasurement.summary` fields, failure) and the seconds spent reading
    (or rendering), refocusing and measuring.
    """
    from ..measure.diagnostics import EmptyPlaneError, measure_flame
    from ..routes import measure_settings
    kw = measure_settings(job.route)
    t = dict(read_s=0.0, refocus_s=0.0, measure_s=0.0)
    rows = []
    for i in range(c * job.chunk, min((c + 1) * job.chunk, job.source.n_frames)):
        t0 = time.perf_counter()
        raw = job.source.raw(i)
        t1 = time.perf_counter()
        try:
            stack = job.planes(job.views(raw))
        except ValueError as e:
            raise ValueError(f"frame {i}: {e}") from None
        t2 = time.perf_counter()
        for k, (plane, d) in enumerate(zip(stack, job.depths_mm)):
            row = dict(frame=i, time_s=i / job.fps, plane=k, depth_mm=d)
            try:
                row.update(measure_flame(plane, job.camera, d, columns=job.columns[k], **kw).summary(), failure="")
            except EmptyPlaneError as e:
                row.update(failure=str(e))
            rows.append(row)
        t3 = time.perf_counter()
        t["read_s"] += t1 - t0
        t["refocus_s"] += t2 - t1
        t["measure_s"] += t3 - t2
    return dict(rows=rows, **t)
