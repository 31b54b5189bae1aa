"""Flame recordings: each plane's flame diagnostics over time, and their flicker spectra.

A recording is a series of raw light-field frames (an HDF5 stack, a folder of image
files, or a simulated :class:`lf_flame.scenes_time.FlameSequence`). Every frame is refocused
at the planes (or reconstructed, :mod:`lf_flame.reconstruct`) and measured per plane by
:func:`lf_flame.diagnostics.measure_flame`; each plane's height and intensity over time
then give its spectrum (Welch, :func:`scipy.signal.welch`) and dominant flicker frequency.

Frames are processed in chunks, serially or as Dask tasks (:mod:`lf_flame.parallel`);
the calling process writes each finished chunk to ``OUT/parts/`` (temporary file, then
rename), so a restart skips the chunks done and a killed worker loses or duplicates no
frame. ``OUT/summary.json`` is written last: a folder without it is not a finished run.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .camera import PlenopticCamera
from .config import atomic_write_text, provenance
from .scenes_time import FlameSequence

#: Per-plane signals whose spectra are computed (columns of the frames table).
SIGNALS = ("height_mm", "integrated_intensity")
#: Image files a folder of frames may hold (read in name order).
FRAME_SUFFIXES = (".tif", ".tiff", ".png", ".npy")
#: Frames per Dask task: enough to make scheduling a small share of the work.
CHUNK = 16


# ---------------------------------------------------------------------------------
# Frame sources: picklable descriptions, opened where the frame is read (in the worker).
@dataclass(frozen=True)
class SimulatedSource:
    """Frames rendered from a :class:`~lf_flame.scenes_time.FlameSequence` (frame ``i`` with ray
    seed ``seed * 1000003 + i``), ``rays_per_pixel`` rays per pixel."""

    sequence: FlameSequence
    camera: PlenopticCamera
    rays_per_pixel: int = 4

    @property
    def n_frames(self) -> int:
        return int(self.sequence.n_frames)

    def raw(self, i: int) -> np.ndarray:
        from .simulate import render
        return render(self.camera, self.sequence.scene(self.camera, i), self.rays_per_pixel,
                      seed=(self.sequence.seed * 1_000_003 + int(i)) % 2**63)

    def identity(self) -> dict:
        return dict(kind="simulated", sequence=self.sequence.to_dict(), rays_per_pixel=self.rays_per_pixel)


@dataclass(frozen=True)
class H5Source:
    """Frames of an HDF5 file: dataset ``frames`` of shape (T, H, W), any real dtype;
    integer frames are scaled by their dtype's maximum, float frames kept."""

    path: str
    dataset: str = "frames"

    @property
    def n_frames(self) -> int:
        import h5py
        with h5py.File(self.path, "r") as f:
            return int(f[self.dataset].shape[0])

    def raw(self, i: int) -> np.ndarray:
        import h5py
        with h5py.File(self.path, "r") as f:
            a = f[self.dataset][int(i)]
        return _scaled(a)

    def identity(self) -> dict:
        st = os.stat(self.path)
        return dict(kind="hdf5", path=str(Path(self.path).resolve()), size=st.st_size, mtime=st.st_mtime)


@dataclass(frozen=True)
class FolderSource:
    """Frames as image files of a folder (:data:`FRAME_SUFFIXES`), in name order."""

    files: tuple

    @property
    def n_frames(self) -> int:
        return len(self.files)

    def raw(self, i: int) -> np.ndarray:
        p = self.files[int(i)]
        if p.endswith(".npy"):
            return _scaled(np.load(p))
        from skimage import io
        return _scaled(np.asarray(io.imread(p)))   # keeps the dtype (load_image returns float64)

    def identity(self) -> dict:
        return dict(kind="folder", files=[str(Path(p).resolve()) for p in self.files])


def _scaled(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[-1] in (3, 4):
        a = a[..., :3].mean(axis=-1)
    if np.issubdtype(a.dtype, np.integer):
        return a.astype(np.float32) * np.float32(1.0 / np.iinfo(a.dtype).max)
    return a.astype(np.float32)


def open_source(path, camera: PlenopticCamera | None = None):
    """The frame source of ``path``: an HDF5 stack (its dataset ``frames``, (T, H, W)) or a
    folder of image files.

    Returns
    -------
    (source, attrs) : the source and the HDF5 file's attributes (``fps``, ``camera``,
        ``sequence`` when written by :func:`write_frames`; empty for a folder).

    Raises
    ------
    ValueError
        A missing path, an empty folder, a file without a 3-D ``frames`` dataset.
    """
    p = Path(path)
    if p.is_dir():
        files = tuple(str(f) for f in sorted(p.iterdir()) if f.suffix.lower() in FRAME_SUFFIXES)
        if not files:
            raise ValueError(f"folder {p} holds no frames ({', '.join(FRAME_SUFFIXES)} files)")
        return FolderSource(files), {}
    if not p.is_file():
        raise ValueError(f"recording not found: {p}")
    import h5py
    try:
        with h5py.File(p, "r") as f:
            if "frames" not in f or f["frames"].ndim != 3 or f["frames"].shape[0] < 1:
                raise ValueError(f"{p} has no 'frames' dataset of shape (T, H, W)")
            attrs = {k: f.attrs[k] for k in f.attrs}
    except OSError as e:
        raise ValueError(f"{p} is not a readable HDF5 file ({e})") from None
    return H5Source(str(p)), attrs


def write_frames(path, source: SimulatedSource, progress: bool = True) -> Path:
    """Render a simulated recording into an HDF5 stack: ``frames`` (T, H, W) uint16 counts
    (x 65535), attributes ``fps``, ``camera`` and ``sequence`` (JSON, the truth); written
    to a temporary file, then renamed."""
    import h5py
    from tqdm import tqdm
    path = Path(path)
    tmp = path.with_name(path.name + ".partial")
    H, W = source.camera.sensor_shape
    with h5py.File(tmp, "w") as f:
        d = f.create_dataset("frames", (source.n_frames, H, W), np.uint16, chunks=(1, H, W), compression="lzf")
        for i in tqdm(range(source.n_frames), desc="frames", disable=not progress):
            d[i] = np.round(np.clip(source.raw(i), 0, 1) * 65535).astype(np.uint16)
        f.attrs.update(fps=source.sequence.fps, camera=source.camera.to_json(),
                       sequence=json.dumps(source.sequence.to_dict()))
    os.replace(tmp, path)
    return path


def frame_rate(fps: float | None, attrs: dict, times_s=None) -> float:
    """The recording's frame rate (frames/s): ``fps`` if given, else the file's ``fps``
    attribute, else from its frame times; both must agree where both exist.

    Parameters
    ----------
    fps : float or None
        Given by the user.
    attrs : dict
        The HDF5 file's attributes (``fps``).
    times_s : ndarray of shape (T,) or None
        Time stamps of the frames (s), e.g. an HDF5 dataset ``times_s``.

    Raises
    ------
    ValueError
        No frame rate anywhere; a rate not positive and finite; time stamps not strictly
        increasing or not evenly spaced (within 1 %); a given rate that disagrees (1 %)
        with the file's.
    """
    found = []
    if fps is not None:
        found.append(("--fps", float(fps)))
    if "fps" in attrs:
        found.append(("the file's fps attribute", float(attrs["fps"])))
    if times_s is not None and len(times_s) > 1:
        dt = np.diff(np.asarray(times_s, float))
        if not np.all(dt > 0):
            raise ValueError(f"frame times are not strictly increasing (at frame {int(np.argmax(dt <= 0)) + 1})")
        if dt.max() - dt.min() > 0.01 * np.median(dt):
            raise ValueError(f"frame times are not evenly spaced ({dt.min():.6g}–{dt.max():.6g} s apart)")
        found.append(("the frame times", 1.0 / float(np.median(dt))))
    if not found:
        raise ValueError("no frame rate: give --fps (frames/s)")
    for name, v in found:
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"frame rate from {name} must be positive and finite. Received: {v}")
        if abs(v - found[0][1]) > 0.01 * found[0][1]:
            raise ValueError(f"frame rate from {name} ({v:g}) disagrees with {found[0][0]} ({found[0][1]:g})")
    return found[0][1]


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
        ``"shift-sum"`` or ``"reconstruct-SOLVER"`` (:data:`lf_flame.reconstruct.SOLVERS`).
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
        from .refocus import raw_to_views
        if not np.all(np.isfinite(raw)):
            raise ValueError("frame holds NaN or inf")
        if self.calibration is None:
            if raw.shape != tuple(self.camera.sensor_shape):
                raise ValueError(f"frame of {raw.shape[0]} x {raw.shape[1]} pixels; the camera's sensor is "
                                 f"{self.camera.sensor_shape[0]} x {self.camera.sensor_shape[1]}")
            return raw_to_views(raw, self.camera.pixels_per_lenslet)
        from .calibrate import GridCalibration, load_image
        from .decode import decode
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
        if self.route == "shift-sum":
            from .refocus import aperture_mask, focal_stack
            n = views.shape[0]
            return focal_stack(views, self.slopes, aperture_mask(n, "circular"))
        from .reconstruct import EmissionOperator, reconstruct
        if "op" not in self._cache:
            self._cache["op"] = EmissionOperator(self.camera, list(self.depths_mm), rays_per_pixel=4)
        return reconstruct(views, self._cache["op"], self.route.split("-", 1)[1]).planes


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
    from .diagnostics import EmptyPlaneError, measure_flame, measure_settings
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


# ---------------------------------------------------------------------------------
def spectra(frames: pd.DataFrame, fps: float, nperseg: int | None = None, signals=SIGNALS) -> pd.DataFrame:
    """Each plane's power spectrum of each signal (Welch, Hann window, mean removed).

    Parameters
    ----------
    frames : DataFrame
        The frames table (columns frame, plane, depth_mm and the ``signals``); a frame
        whose plane could not be measured (NaN) takes the plane's mean.
    fps : float
        Frame rate (frames/s).
    nperseg : int or None
        Welch segment length (frames); None: the whole record, so the bin is 1/T.

    Returns
    -------
    DataFrame with columns plane, depth_mm, signal, freq_hz, power (the signal's unit
    squared: ``scaling="spectrum"``, a sinusoid of amplitude a on a bin has power a²/2).
    """
    from scipy.signal import welch
    out = []
    for (k, d), g in frames.groupby(["plane", "depth_mm"], sort=True):
        g = g.sort_values("frame")
        for s in signals:
            x = g[s].to_numpy(float)
            x = np.where(np.isfinite(x), x, np.nanmean(x) if np.isfinite(x).any() else 0.0)
            f, p = welch(x, fs=fps, nperseg=min(nperseg or len(x), len(x)), detrend="constant", scaling="spectrum")
            out.append(pd.DataFrame(dict(plane=k, depth_mm=d, signal=s, freq_hz=f, power=p)))
    return pd.concat(out, ignore_index=True)


def peaks(spec: pd.DataFrame, truth_freqs_hz=None) -> pd.DataFrame:
    """Dominant frequency of each plane and signal (the largest power above 0 Hz), its
    amplitude ``sqrt(2 P)``, and where the true frequencies are known (one per plane, plane
    ``k`` holding flame ``k``): the true frequency, the error in bins, and how far (dB) the
    other flames' frequencies lie below the plane's own on its spectrum (the worst of them).
    """
    rows = []
    for (k, d, s), g in spec.groupby(["plane", "depth_mm", "signal"], sort=False):
        f, p = g.freq_hz.to_numpy(), g.power.to_numpy()
        j = 1 + int(np.argmax(p[1:]))
        df = f[1] - f[0]
        row = dict(plane=k, depth_mm=d, signal=s, bin_hz=df, dominant_hz=f[j], amplitude=math.sqrt(2 * p[j]))
        if truth_freqs_hz is not None:
            def power_at(hz):   # the largest power within one bin of hz (a tone off the bin grid splits)
                return float(p[np.abs(f - hz) <= df].max())
            own = truth_freqs_hz[k]
            others = [v for i, v in enumerate(truth_freqs_hz) if i != k]
            row.update(true_hz=own, error_bins=abs(f[j] - own) / df, within_one_bin=abs(f[j] - own) <= df)
            if others:
                below = [10 * math.log10(power_at(own) / max(power_at(v), 1e-300)) for v in others]
                row.update(others_below_db=min(below), worst_other_hz=others[int(np.argmin(below))])
        rows.append(row)
    return pd.DataFrame(rows)


def plot_sequence(path, frames: pd.DataFrame, spec: pd.DataFrame, pk: pd.DataFrame, title: str = "") -> None:
    """Figure: each plane's height against time (truth dashed when known) and its spectrum
    (true frequency marked)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    planes = sorted(frames.plane.unique())
    fig, axes = plt.subplots(len(planes), 2, figsize=(11, 2.0 * len(planes) + 0.6), squeeze=False)
    for ax, k in zip(axes, planes):
        g = frames[frames.plane == k].sort_values("frame")
        d = g.depth_mm.iloc[0]
        ax[0].plot(g.time_s, g.height_mm, lw=0.8, label="measured")
        if "height_mm_true" in g:
            ax[0].plot(g.time_s, g.height_mm_true, "k--", lw=0.6, label="true")
        ax[0].set_ylabel(f"{d:+g} mm\nheight (mm)")
        s = spec[(spec.plane == k) & (spec.signal == "height_mm")]
        ax[1].semilogy(s.freq_hz, s.power + 1e-12, lw=0.8)
        p = pk[(pk.plane == k) & (pk.signal == "height_mm")].iloc[0]
        ax[1].axvline(p.dominant_hz, color="C1", lw=0.8, label=f"peak {p.dominant_hz:.1f} Hz")
        if "true_hz" in p and np.isfinite(p.get("true_hz", np.nan)):
            ax[1].axvline(p.true_hz, color="k", ls="--", lw=0.6, label=f"true {p.true_hz:.2f} Hz")
        ax[1].set_xlim(0, min(s.freq_hz.max(), 60))
        ax[1].set_ylabel("power (mm²)")
        ax[1].legend(fontsize=7, loc="upper right")
    axes[0][0].legend(fontsize=7, loc="upper right")
    axes[-1][0].set_xlabel("time (s)")
    axes[-1][1].set_xlabel("frequency (Hz)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------
def _write_csv(path: Path, df: pd.DataFrame) -> None:
    atomic_write_text(path, df.to_csv(index=False, float_format="%.6g"))


def run(job: SequenceJob, out, *, scheduler: str | None = None, workers: int | None = None, nperseg=None,
        truth=None, progress: bool = True) -> dict:
    """Process a recording into ``out``: frames.csv, spectra.csv, peaks.csv, sequence.png
    and, last, summary.json (settings, timings, provenance).

    Serial (Numba's threads) when ``scheduler`` and ``workers`` are None, else on Dask:
    ``workers`` local worker processes of one thread, or the cluster at ``scheduler``.
    Chunks already in ``out/parts`` are skipped; both paths write the same tables.

    Parameters
    ----------
    job : SequenceJob
    out : path-like
        Output folder (created).
    truth : ndarray of shape (T, P) or None
        True heights (mm) of plane k's flame per frame: a ``height_mm_true`` column.

    Returns
    -------
    dict : the summary: ``wall_s`` and ``frames_per_s`` of the chunks processed, from the
        moment the cluster is up (``startup_s``, its start); ``busy_s``, the seconds the
        tasks spent reading (or rendering), refocusing and measuring.

    Raises
    ------
    ValueError
        ``out`` holds a run with other settings; a frame that cannot be processed (NaN,
        wrong size); a chunk table that does not hold its frames exactly once.
    """
    out = Path(out)
    parts = out / "parts"
    parts.mkdir(parents=True, exist_ok=True)
    ident = json.dumps(job.identity(), sort_keys=True, default=float)
    jf = out / "job.json"
    if jf.exists() and jf.read_text() != ident:
        raise ValueError(f"{out} holds a run with other settings (job.json); give another --out or delete it")
    (out / "summary.json").unlink(missing_ok=True)   # not finished until written again
    atomic_write_text(jf, ident)
    todo = [c for c in range(job.n_chunks) if not (parts / f"chunk-{c:05d}.csv").exists()]
    t0 = time.perf_counter()
    busy = dict(read_s=0.0, refocus_s=0.0, measure_s=0.0)

    def keep(c, res):
        df = pd.DataFrame(res["rows"])
        want = list(range(c * job.chunk, min((c + 1) * job.chunk, job.source.n_frames)))
        if sorted(df.frame.unique()) != want or len(df) != len(want) * len(job.depths_mm):
            raise ValueError(f"chunk {c} returned frames {sorted(df.frame.unique())}, expected {want}")
        _write_csv(parts / f"chunk-{c:05d}.csv", df)
        for k in busy:
            busy[k] += res[k]

    if scheduler is None and workers is None:
        from tqdm import tqdm
        startup = 0.0
        for c in tqdm(todo, desc="chunks", disable=not progress):
            keep(c, process_chunk(c, job))
        n_workers = 0
    else:
        from .parallel import dask_client, map_unordered
        with dask_client(scheduler, workers or 1) as client:
            n_workers = len(client.nthreads())
            client.run(_warm_up, job)   # imports and Numba's cached kernels, counted in the start-up
            startup = time.perf_counter() - t0
            t0 += startup
            # keys carry the run's identity: two recordings on one shared scheduler never share a task
            tag = hashlib.sha256(ident.encode()).hexdigest()[:8]
            for c, res in map_unordered(client, process_chunk, todo, job, name=f"frames-{tag}", progress=progress,
                                        total=len(todo)):
                keep(c, res)
    wall = time.perf_counter() - t0
    frames = pd.concat([pd.read_csv(parts / f"chunk-{c:05d}.csv", keep_default_na=False, na_values=[""])
                        for c in range(job.n_chunks)], ignore_index=True).sort_values(["frame", "plane"])
    counts = frames.groupby("frame").size()
    if len(counts) != job.source.n_frames or (counts != len(job.depths_mm)).any():
        raise ValueError(f"{parts} does not hold every frame exactly once; delete it and run again")
    if truth is not None:
        frames["height_mm_true"] = np.asarray(truth, float)[frames.frame.to_numpy(), frames.plane.to_numpy()]
        frames["height_err_mm"] = frames.height_mm - frames.height_mm_true
    spec = spectra(frames, job.fps, nperseg)
    pk = peaks(spec, job.truth_freqs_hz)
    _write_csv(out / "frames.csv", frames)
    _write_csv(out / "spectra.csv", spec)
    _write_csv(out / "peaks.csv", pk)
    plot_sequence(out / "sequence.png", frames, spec, pk,
                  f"{job.source.n_frames} frames at {job.fps:g} frames/s, route {job.route}")
    summary = dict(settings=job.identity(), n_frames=job.source.n_frames, chunks_processed=len(todo),
                   workers=n_workers, scheduler=scheduler, startup_s=startup, wall_s=wall,
                   frames_per_s=(len(todo) and sum(min(job.chunk, job.source.n_frames - c * job.chunk)
                                                   for c in todo) / wall),
                   busy_s=busy, provenance=provenance())
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=1, default=float))
    return summary
