"""Frame sources of a recording and its frame rate.

A recording is a series of raw light-field frames: an HDF5 stack, a multi-page TIFF (a
high-speed camera's or ImageJ's stack), a folder of image files, or a simulated
:class:`lf_flame.simulate.scenes_time.FlameSequence`. The sources are picklable descriptions,
opened where the frames are read (in the worker).
"""
from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from ..optics.camera import PlenopticCamera
from ..real.images import frame_image, frame_units as _scaled
from ..simulate.scenes_time import FlameSequence

#: Image files a folder of frames may hold (read in the order of the numbers in their names: frame_2 before frame_10).
FRAME_SUFFIXES = (".tif", ".tiff", ".png", ".npy")


# ---------------------------------------------------------------------------------
# Frame sources: picklable descriptions, opened where the frame is read (in the worker).
@dataclass(frozen=True)
class SimulatedSource:
    """Frames rendered from a :class:`~lf_flame.simulate.scenes_time.FlameSequence` (frame ``i`` with ray
    seed ``seed * 1000003 + i``), ``rays_per_pixel`` rays per pixel; with a colour ``sensor``
    (:class:`lf_flame.optics.colour.ColourSensor`) each flame with its temperature field through the sensor's
    mosaic (:func:`lf_flame.simulate.scenes_temperature.colour_flicker_frame`, the sheath temperatures
    :meth:`sheath_temperatures`, one exposure for the recording: its first frame's;
    :func:`lf_flame.simulate.colour.render_colour`)."""

    sequence: FlameSequence
    camera: PlenopticCamera
    rays_per_pixel: int = 4
    sensor: object = None

    @property
    def n_frames(self) -> int:
        return int(self.sequence.n_frames)

    @cached_property
    def peaks_k(self) -> tuple:
        """Each flame's mean sheath temperature, K (:func:`~lf_flame.simulate.scenes_temperature.flicker_peaks`)."""
        from ..simulate.scenes_temperature import flicker_peaks
        return flicker_peaks(len(self.sequence.flames))

    @cached_property
    def exposure(self) -> float:
        """A colour recording's exposure: the one that brings its first frame's brightest texel to 0.8."""
        from ..simulate.scenes_temperature import colour_flicker_frame
        return colour_flicker_frame(self.sequence, self.camera, self.sensor, 0, peaks_k=self.peaks_k).exposure

    def sheath_temperatures(self, i: int) -> list:
        """A colour recording's truth: each flame's sheath temperature (K) in frame ``i``."""
        from ..simulate.scenes_temperature import sheath_temperatures
        return sheath_temperatures(self.sequence, i, self.peaks_k)

    def raw(self, i: int) -> np.ndarray:
        seed = (self.sequence.seed * 1_000_003 + int(i)) % 2**63
        if self.sensor is None:
            from ..simulate.tracer import render
            return render(self.camera, self.sequence.scene(self.camera, i), self.rays_per_pixel, seed=seed)
        from ..simulate.colour import render_colour
        from ..simulate.scenes_temperature import colour_flicker_frame
        cs = colour_flicker_frame(self.sequence, self.camera, self.sensor, i, peaks_k=self.peaks_k,
                                  exposure=self.exposure)
        return render_colour(self.camera, cs.scene, cs.channel_radiance, self.sensor, self.rays_per_pixel, seed)

    def identity(self) -> dict:
        out = dict(kind="simulated", sequence=self.sequence.to_dict(), rays_per_pixel=self.rays_per_pixel)
        return out if self.sensor is None else dict(out, sensor=self.sensor.record())

    def frames(self, start: int, stop: int):
        """Frames ``start`` to ``stop`` (exclusive): an iterator of (H, W) float32 images."""
        return (self.raw(i) for i in range(int(start), int(stop)))


@dataclass(frozen=True)
class H5Source:
    """Frames of an HDF5 file: dataset ``frames`` of shape (T, H, W), any real dtype;
    integer frames are scaled by their dtype's maximum, float frames kept."""

    path: str
    dataset: str = "frames"

    @cached_property
    def n_frames(self) -> int:
        """Frames in the file (read once, then kept: it travels with the source)."""
        import h5py
        with h5py.File(self.path, "r") as f:
            return int(f[self.dataset].shape[0])

    def raw(self, i: int) -> np.ndarray:
        """Frame ``i`` (H, W) float32, the file opened for it alone (:meth:`frames` reads a
        run of frames in one open)."""
        import h5py
        with h5py.File(self.path, "r") as f:
            a = f[self.dataset][int(i)]
        return _scaled(a)

    def frames(self, start: int, stop: int):
        """Frames ``start`` to ``stop`` (exclusive), read in one open of the file: an
        iterator of (H, W) float32 images, one frame in memory at a time (a chunk read as one
        slice and scaled at once is 16 x 14.6 MB of float32 on the paper's sensor, slower
        to read than frame by frame: ``make sequence``, the speed stage)."""
        import h5py
        with h5py.File(self.path, "r") as f:
            d = f[self.dataset]
            for i in range(int(start), int(stop)):
                yield _scaled(d[i])

    def identity(self) -> dict:
        st = os.stat(self.path)
        return dict(kind="hdf5", path=str(Path(self.path).resolve()), size=st.st_size, mtime=st.st_mtime)


@dataclass(frozen=True)
class FolderSource:
    """Frames as image files of a folder (:data:`FRAME_SUFFIXES`), in the order of their names' numbers
    (:func:`frame_order`); None in ``files`` for a frame whose number the files skip (:func:`numbered_gaps`)."""

    files: tuple

    @property
    def n_frames(self) -> int:
        return len(self.files)

    def raw(self, i: int) -> np.ndarray:
        f = self.files[int(i)]
        if f is None:
            raise ValueError(f"frame {int(i)} is missing from the folder: the numbers of its files skip it")
        return frame_image(f)

    def identity(self) -> dict:
        """The files (absolute paths), each with its size and modification time (a changed frame
        is another recording); None for a missing frame."""
        stats = [None if p is None else os.stat(p) for p in self.files]
        return dict(kind="folder", files=[None if p is None else str(Path(p).resolve()) for p in self.files],
                    stats=[None if st is None else [st.st_size, st.st_mtime] for st in stats])

    def frames(self, start: int, stop: int):
        """Frames ``start`` to ``stop`` (exclusive): an iterator of (H, W) float32 images."""
        return (self.raw(i) for i in range(int(start), int(stop)))


@dataclass(frozen=True)
class TiffStackSource:
    """Frames as the pages of one multi-page TIFF file (its first series, (T, H, W): a high-speed camera's or
    ImageJ's stack; tifffile), any real dtype; integer frames are scaled by their dtype's maximum, float frames
    kept."""

    path: str

    @cached_property
    def n_frames(self) -> int:
        """Frames in the file (read once, then kept: it travels with the source)."""
        import tifffile
        with tifffile.TiffFile(self.path) as tf:
            return _stack_frames(tf, self.path)

    def raw(self, i: int) -> np.ndarray:
        """Frame ``i`` (H, W) float32, the file opened for it alone."""
        import tifffile
        with tifffile.TiffFile(self.path) as tf:
            return _scaled(tf.asarray(key=int(i), series=0))

    def frames(self, start: int, stop: int):
        """Frames ``start`` to ``stop`` (exclusive), read in one open of the file, one in memory at a time: an
        iterator of (H, W) float32 images."""
        import tifffile
        with tifffile.TiffFile(self.path) as tf:
            for i in range(int(start), int(stop)):
                yield _scaled(tf.asarray(key=i, series=0))

    def identity(self) -> dict:
        st = os.stat(self.path)
        return dict(kind="tiff", path=str(Path(self.path).resolve()), size=st.st_size, mtime=st.st_mtime)


def _stack_frames(tf, path) -> int:
    """The frames of an open TIFF's first series: (T, H, W) or one (H, W) page; anything else is refused."""
    if not tf.series:
        raise ValueError(f"{path} holds no image")
    shape = tuple(tf.series[0].shape)
    if len(shape) == 2 or (len(shape) == 3 and shape[-1] in (3, 4) and len(tf.series[0].pages) == 1):
        return 1                                              # one frame (gray, or colour averaged to gray)
    if len(shape) == 3 or (len(shape) == 4 and shape[-1] in (3, 4)):
        return shape[0]                                       # frames (colour ones averaged to gray)
    raise ValueError(f"{path}: a TIFF of shape {shape} is not a stack of frames (T, H, W)")


#: ImageJ's time units (its ``tunit``) in seconds.
_TIME_UNITS = {"sec": 1.0, "s": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "msec": 1e-3, "us": 1e-6,
               "\u00b5s": 1e-6, "usec": 1e-6}


def _imagej_rate(meta: dict) -> dict:
    """``{"fps": ...}`` from an ImageJ stack's frame interval (``finterval``, in its ``tunit``, seconds by default);
    empty where it has none or a time unit not known here."""
    interval, unit = meta.get("finterval"), str(meta.get("tunit", "sec")).strip().lower()
    if not interval or unit not in _TIME_UNITS:
        return {}
    return {"fps": 1.0 / (float(interval) * _TIME_UNITS[unit])}


def numbered_gaps(files) -> tuple:
    """A folder's frame files (in :func:`frame_order`) with None where the numbers in their names skip a frame: where
    every name is the same text about one run of digits (``frame_0007.tif``), the numbers step by their greatest
    common step and some are missing. Each frame is timed by its place (``i / fps``): a missing file had moved every
    later frame one frame early (a user's flicker read at 20.20 Hz for 19.34). Other folders as they are.

    Parameters
    ----------
    files : sequence of str

    Returns
    -------
    tuple of str or None
    """
    parts = [re.fullmatch(r"(.*?)(\d+)(\D*)", Path(f).name) for f in files]
    if len(files) < 3 or not all(parts) or len({(m.group(1), m.group(3)) for m in parts}) != 1:
        return tuple(files)
    numbers = [int(m.group(2)) for m in parts]
    step = math.gcd(*np.diff(numbers).tolist())
    if step < 1 or len(set(numbers)) != len(numbers):
        return tuple(files)
    at = {n: f for n, f in zip(numbers, files)}
    return tuple(at.get(n) for n in range(numbers[0], numbers[-1] + 1, step))


def tolerant_frames(source, start: int, stop: int):
    """Frames ``start`` to ``stop`` (exclusive) of ``source`` as its ``frames`` gives them, but a folder's frame that
    cannot be read (a truncated file, a missing one: :func:`numbered_gaps`) comes as the ValueError saying why, in
    its place, so that a recording goes on past it (one unreadable file had stopped the whole run)."""
    if not isinstance(source, FolderSource):
        yield from source.frames(start, stop)
        return
    for i in range(int(start), int(stop)):
        try:
            yield source.raw(i)
        except (ValueError, OSError) as e:
            yield ValueError(str(e))


def frame_order(name: str) -> list:
    """The sort key of a frame's file name: its runs of digits as numbers, the rest as text (case folded), so that
    ``frame_2.png`` comes before ``frame_10.png`` whether or not the numbers are padded with zeros."""
    return [(0, int(t), "") if t.isdigit() else (1, 0, t.lower()) for t in re.split(r"(\d+)", name) if t]


def open_source(path, camera: PlenopticCamera | None = None):
    """The frame source of ``path``: an HDF5 stack (its dataset ``frames``, (T, H, W)), a
    multi-page TIFF (.tif, .tiff: its pages, :class:`TiffStackSource`) or a folder of image files.

    Returns
    -------
    (source, attrs) : the source and the HDF5 file's attributes (``fps``, ``camera``,
        ``sequence`` when written by :func:`write_frames`); a TIFF's ``fps`` from its ImageJ frame
        interval where it has one; empty for a folder.

    Raises
    ------
    ValueError
        A missing path, an empty folder, a file without a 3-D ``frames`` dataset, a TIFF that is
        not a stack of 2-D frames or cannot be read.
    """
    p = Path(path)
    if p.is_dir():
        files = tuple(str(f) for f in sorted(p.iterdir(), key=lambda f: frame_order(f.name))
                      if f.suffix.lower() in FRAME_SUFFIXES)
        if not files:
            raise ValueError(f"folder {p} holds no frames ({', '.join(FRAME_SUFFIXES)} files)")
        numbered = numbered_gaps(files)
        missing = [i for i, f in enumerate(numbered) if f is None]
        if missing:
            print(f"warning: folder {p}: the numbers of its files skip {len(missing)} frame"
                  f"{'s' * (len(missing) != 1)} (frames {', '.join(map(str, missing[:5]))}"
                  f"{' ...' if len(missing) > 5 else ''}, counted from its first file): each is a failed row at its "
                  "time, and the frames after it keep theirs")
        return FolderSource(numbered), {}
    if not p.is_file():
        indexed = re.search(r":\d+$", str(p))
        hint = " (a recording's frames are all measured: give the file, not FILE:INDEX)" if indexed else ""
        raise ValueError(f"recording not found: {p}{hint}")
    if p.suffix.lower() in (".npy", ".npz", ".png"):      # one light field, not a recording
        raise ValueError(f"{p} is one light field, not a recording: a recording is an HDF5 file with a 'frames' stack "
                         "(T, H, W), a multi-page TIFF or a folder of frames; one capture goes to 'lf-flame "
                         "reconstruct' or 'profiles'")
    if p.suffix.lower() in (".tif", ".tiff"):
        import tifffile
        try:
            with tifffile.TiffFile(p) as tf:
                _stack_frames(tf, p)
                meta = tf.imagej_metadata or {}
        except (tifffile.TiffFileError, OSError) as e:
            raise ValueError(f"{p} is not a readable TIFF: {e}") from None
        return TiffStackSource(str(p)), _imagej_rate(meta)
    import h5py
    from ..config import reading
    with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
        if "frames" not in f or f["frames"].ndim != 3 or f["frames"].shape[0] < 1:
            raise ValueError(f"{p} has no 'frames' dataset of shape (T, H, W)")
        attrs = {k: f.attrs[k] for k in f.attrs}
    return H5Source(str(p)), attrs


def write_frames(path, source: SimulatedSource, progress: bool = True) -> Path:
    """Render a simulated recording into an HDF5 stack: ``frames`` (T, H, W) uint16 counts
    (x 65535), attributes ``fps``, ``camera`` and ``sequence`` (JSON, the truth); a colour recording
    also ``sensor`` (JSON: ``name``, ``pattern``, ``phase``, as ``lf-flame simulate`` records a capture's) and
    ``sheath_temperature_k`` (T, flames) float64, each flame's sheath temperature per frame (K; attribute
    ``flicker_k``, their amplitude). Written to ``PATH.partial``, then renamed.

    A run stopped part-way (an error, Ctrl-C) leaves ``PATH.partial`` holding the frames
    written so far (each marked in its dataset ``done`` once written) and the settings it was
    made for (attribute ``settings``: the source's identity and camera). The next run with the
    same settings renders only the frames not done (each frame has its own seed: the file is
    the one an uninterrupted run writes); a partial file of other settings, or one that cannot
    be read, is started over. Both are said on stdout.
    """
    from tqdm import tqdm
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".partial")
    n, (H, W) = source.n_frames, source.camera.sensor_shape
    settings = json.dumps(dict(source.identity(), camera=source.camera.to_json()), sort_keys=True)
    f = _resumed_frames(tmp, settings, (n, H, W))
    with f:
        done, d = f["done"], f["frames"]
        todo = np.flatnonzero(done[:] == 0)
        for i in tqdm(todo, desc="frames", disable=not progress, initial=n - len(todo), total=n):
            d[i] = np.round(np.clip(source.raw(int(i)), 0, 1) * 65535).astype(np.uint16)
            f.flush()
            done[i] = 1            # marked after its frame is on disk: a stop in between renders it again
            f.flush()
        del f["done"]
        f.attrs.update(fps=source.sequence.fps, camera=source.camera.to_json(),
                       sequence=json.dumps(source.sequence.to_dict()))
        if source.sensor is not None:
            from ..simulate.scenes_temperature import FLICKER_K
            f.attrs["sensor"] = json.dumps(source.sensor.record())
            truth = f.create_dataset("sheath_temperature_k", data=[source.sheath_temperatures(i) for i in range(n)])
            truth.attrs["flicker_k"] = FLICKER_K
    os.replace(tmp, path)
    return path


def _resumed_frames(tmp: Path, settings: str, shape: tuple):
    """:func:`write_frames`' partial file, open for writing: ``tmp`` resumed when it was made for
    ``settings`` (frames of ``shape``), else (other settings, unreadable, absent) a new one."""
    import h5py
    if tmp.exists():
        try:
            f = h5py.File(tmp, "r+")
        except OSError:
            f = None
        if f is not None and (f.attrs.get("settings") == settings and "done" in f and "frames" in f
                              and f["frames"].shape == tuple(shape)):
            n_done = int(f["done"][:].sum())
            print(f"{tmp}: resuming, {n_done} of {shape[0]} frames already written")
            return f
        if f is not None:
            f.close()
        print(f"{tmp} was written for other settings (or cannot be read): starting over")
    f = h5py.File(tmp, "w")
    f.attrs["settings"] = settings
    f.create_dataset("frames", shape, np.uint16, chunks=(1, *shape[1:]), compression="lzf")
    f.create_dataset("done", (shape[0],), np.uint8, fillvalue=0)
    return f


def source_frame_rate(source, attrs: dict, fps: float | None = None) -> float:
    """The frame rate of a recording opened by :func:`open_source` (:func:`frame_rate`), with an HDF5 stack's frame
    times (its dataset ``times_s``, one per frame: another count is refused naming both) where it holds them."""
    times = None
    if isinstance(source, H5Source):
        import h5py
        with h5py.File(source.path, "r") as f:
            times = f["times_s"][:] if "times_s" in f else None
        if times is not None and np.shape(times) != (source.n_frames,):
            raise ValueError(f"{source.path}: its frame times (dataset times_s) hold {np.size(times)} times of shape "
                             f"{np.shape(times)} for its {source.n_frames} frames: give one time per frame (s), or "
                             "delete times_s and give --fps")
    return frame_rate(fps, attrs, times)


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
        No frame rate anywhere; a rate not positive and finite; an ``fps`` attribute that is not a number; time
        stamps with NaN or inf, not strictly increasing or not evenly spaced (within 1 %); a given rate that
        disagrees (1 %) with the file's.
    """
    found = []
    if fps is not None:
        found.append(("--fps", float(fps)))
    if "fps" in attrs:
        try:
            found.append(("the file's fps attribute", float(attrs["fps"])))
        except (TypeError, ValueError):
            raise ValueError(f"the file's fps attribute must be a number (frames/s). Received: {attrs['fps']!r}; "
                             "correct it, or delete it and give --fps") from None
    if times_s is not None and len(times_s) > 1:
        try:
            t = np.asarray(times_s, float)
        except (TypeError, ValueError):
            raise ValueError("the frame times (times_s) must be numbers (s)") from None
        if not np.all(np.isfinite(t)):
            raise ValueError(f"the frame times (times_s) hold NaN or inf (first at frame "
                             f"{int(np.argmax(~np.isfinite(t)))}): correct them, or delete times_s and give --fps")
        dt = np.diff(t)
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
