"""Running a recording serially or on Dask, resumably.

Frames are processed in chunks, serially or as Dask tasks (:mod:`lf_flame.parallel`);
the calling process writes each finished chunk to ``OUT/parts/`` (temporary file, then
rename), so a restart skips the chunks done and a killed worker loses or duplicates no
frame. ``OUT/summary.json`` is written last: a folder without it is not a finished run.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..config import atomic_write_text, provenance
from .chunk import UNPROCESSED_FRAME, _warm_up, process_chunk
from .job import NONFINITE_FRAME, SequenceJob
from .plot import plot_sequence
from .flicker import SIGNALS, peaks, spectra


#: A frame whose clipped pixels are more than :data:`~lf_flame.real.clipping.CLIPPED_WARN` of its lit ones and more than
#: this many times the recording's median share is over-exposed against the others (a flash, a reflection, an exposure
#: step): its measurements stay in frames.csv but its spectrum takes the plane's mean there, as for a frame that could
#: not be measured (:func:`over_exposed_frames`). A recording whose every frame clips alike keeps them all.
OVER_EXPOSED_RATIO = 2.0


# ---------------------------------------------------------------------------------
def over_exposed_frames(frames: pd.DataFrame) -> list:
    """The frames over-exposed against the rest of their recording (:data:`OVER_EXPOSED_RATIO`).

    Parameters
    ----------
    frames : DataFrame
        The frames table (columns ``frame`` and, on ``reconstruct-*`` routes, ``clipped_share``: the clipped pixels'
        share of the lit ones per frame).

    Returns
    -------
    list of int
        The frames, ascending; none without a ``clipped_share`` column.
    """
    from ..real.clipping import CLIPPED_WARN
    if "clipped_share" not in frames:
        return []
    share = frames.groupby("frame").clipped_share.first().fillna(0.0)
    typical = float(share.median())
    return [int(f) for f, v in share.items() if v > CLIPPED_WARN and v > OVER_EXPOSED_RATIO * typical]


def frame_failures(frames: pd.DataFrame) -> dict:
    """The frames that failed as a whole, on every plane (NaN or inf, :data:`~lf_flame.recordings.job.NONFINITE_FRAME`;
    not processed, :data:`~lf_flame.recordings.chunk.UNPROCESSED_FRAME`), each with its failure.

    Parameters
    ----------
    frames : DataFrame
        The frames table (columns ``frame``, ``failure``).

    Returns
    -------
    dict of int to str
        Frame -> failure, ascending.
    """
    fail = frames.failure.map(lambda v: v if isinstance(v, str) else "")     # all NaN where none failed
    whole = (fail == NONFINITE_FRAME) | fail.str.startswith(UNPROCESSED_FRAME)
    return {int(f): str(m) for f, m in frames[whole].groupby("frame").failure.first().sort_index().items()}


def recording_spectra(frames: pd.DataFrame, fps: float, nperseg: int | None = None):
    """Each plane's spectra (:func:`~lf_flame.recordings.flicker.spectra`) with the frames over-exposed against the
    rest (:func:`over_exposed_frames`) taking the plane's mean, as a frame that could not be measured does.

    Returns
    -------
    spectra : DataFrame
    over_exposed : list of int
        The frames left out.
    """
    over = over_exposed_frames(frames)
    measured = frames.copy()
    measured.loc[measured.frame.isin(over), list(SIGNALS)] = np.nan
    return spectra(measured, fps, nperseg), over


def _write_csv(path: Path, df: pd.DataFrame) -> None:
    atomic_write_text(path, df.to_csv(index=False, float_format="%.6g"))


def _recording(ident: dict):
    """Where a run's frames come from (the source's kind and path or files), without their size and time."""
    src = ident.get("source") or {}
    return src.get("kind"), src.get("path"), tuple(src.get("files") or ())


def _settings(ident: dict) -> dict:
    """A run's settings but its recording's contents: the reconstruction's knobs chosen by the
    first frame's noise (admm) left out with them."""
    rec = ident.get("reconstruction")
    keep = None if rec is None else {k: rec.get(k) for k in ("solver", "saturation", "operator_rays")}
    return {**{k: v for k, v in ident.items() if k not in ("source", "reconstruction")}, "reconstruction": keep}


def _start_over_or_refuse(out: Path, old: str, new: str) -> None:
    """``out`` holds the job of another run (``old``, job.json) than this one (``new``). Start over,
    saying so, when the recording file changed since (the same path and settings, another size or
    time: e.g. a frame fixed after the run failed on it; its chunks done are stale and removed) or
    when the other run never finished a chunk; else refuse: its results are another run's.

    Raises
    ------
    ValueError
        The folder holds another run's chunks or results.
    """
    try:
        old_id = json.loads(old)
    except json.JSONDecodeError:
        old_id = {}
    new_id = json.loads(new)
    parts = sorted((out / "parts").glob("chunk-*.csv"))
    kind, path, files = _recording(new_id)
    if (kind in ("hdf5", "folder") and _recording(old_id) == (kind, path, files)
            and old_id.get("source") != new_id["source"] and _settings(old_id) == _settings(new_id)):
        print(f"{path or Path(files[0]).parent} changed since the run in {out} (size or modification time): "
              f"starting over{f' ({len(parts)} chunks done from the old frames removed)' if parts else ''}")
        for p in parts:
            p.unlink()
        return
    if not parts and not (out / "summary.json").exists():
        print(f"{out} holds an unfinished run of other settings with no chunk done: starting over")
        return
    differ = sorted(k for k in set(old_id) | set(new_id) if old_id.get(k) != new_id.get(k))
    shown = ", ".join(f"{k} {_short(old_id.get(k))} there, {_short(new_id.get(k))} now" for k in differ[:3])
    raise ValueError(f"{out} holds a run with other settings (job.json{': ' + shown if shown else ''}"
                     f"{f' and {len(differ) - 3} more' if len(differ) > 3 else ''}); give another --out or delete it")


def _short(v, n: int = 40) -> str:
    """A setting's value for a message: its JSON, cut to ``n`` characters."""
    text = json.dumps(v, default=str)
    return text if len(text) <= n else text[:n - 3] + "..."


#: The summary's timings of the chunks a run processed: a rerun that finds every chunk done keeps the last run's (it
#: had written 0 frames/s over theirs).
TIMINGS = ("workers", "scheduler", "startup_s", "wall_s", "frames_per_s", "busy_s", "chunks_processed")


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
        tasks spent reading (or rendering), refocusing and measuring; ``failed_frames``,
        each plane's frames that could not be measured (their values in its spectrum are
        the plane's mean; also ``n_failed`` in peaks.csv); ``unprocessed_frames``, the frames that failed on every
        plane with why (:func:`frame_failures`); on ``reconstruct-*`` routes
        ``n_saturated``, the frames with saturated pixels left out of the fit and the most
        in one frame, and ``over_exposed``, the frames whose clipped pixels are more than
        :data:`~lf_flame.real.clipping.CLIPPED_WARN` of the lit ones, the largest share, the frames that clip
        at all and those over-exposed against the rest (:func:`over_exposed_frames`: their values in the spectra
        are the plane's mean; also ``n_over_exposed`` in peaks.csv) (per frame: frames.csv).

    Raises
    ------
    ValueError
        ``out`` holds a run with other settings; a recording of fewer than 2 frames (no
        spectrum); ``nperseg`` below 2; a recording none of whose frames could be processed (a frame with NaN or
        inf, of another size, every sample clipped ... is a failed row naming why,
        :func:`~lf_flame.recordings.chunk.process_chunk`, unless every frame is: :func:`frame_failures`);
        a chunk table that does not hold its frames exactly once.
    """
    out = Path(out)
    if job.source.n_frames < 2:
        raise ValueError(f"a recording of {job.source.n_frames} frame has no spectrum: give at least 2 frames")
    if nperseg is not None and (int(nperseg) != nperseg or nperseg < 2):
        raise ValueError(f"nperseg (Welch segment, frames) must be a whole number >= 2. Received: {nperseg!r}")
    parts = out / "parts"
    parts.mkdir(parents=True, exist_ok=True)
    ident = json.dumps(job.identity(), sort_keys=True, default=float)
    jf = out / "job.json"
    if jf.exists() and jf.read_text() != ident:
        _start_over_or_refuse(out, jf.read_text(), ident)
    try:                                             # its timings, for a rerun that finds every chunk done
        before = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        before = {}
    (out / "summary.json").unlink(missing_ok=True)   # not finished until written again
    atomic_write_text(jf, ident)
    def frames_of(c):
        return list(range(c * job.chunk, min((c + 1) * job.chunk, job.source.n_frames)))

    def whole(df, c):
        return sorted(df.frame.unique()) == frames_of(c) and len(df) == len(frames_of(c)) * len(job.depths_mm)

    damaged = []
    for c in range(job.n_chunks):           # a chunk file damaged since it was written: done again, not refused
        f = parts / f"chunk-{c:05d}.csv"
        if f.exists():
            try:
                ok = whole(pd.read_csv(f, keep_default_na=False, na_values=[""]), c)
            except (ValueError, KeyError, pd.errors.ParserError):
                ok = False
            if not ok:
                f.unlink()
                damaged.append(c)
    if damaged:
        print(f"{len(damaged)} chunk file(s) of {parts} damaged since written (chunk {damaged[0]} ...): done again")
    todo = [c for c in range(job.n_chunks) if not (parts / f"chunk-{c:05d}.csv").exists()]
    t0 = time.perf_counter()
    busy = dict(read_s=0.0, refocus_s=0.0, measure_s=0.0)

    def keep(c, res):
        df = pd.DataFrame(res["rows"])
        if not whole(df, c):
            raise ValueError(f"chunk {c} returned frames {sorted(df.frame.unique())}, expected {frames_of(c)}")
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
        from ..parallel import dask_client, map_unordered, prepare_workers
        with dask_client(scheduler, workers or 1) as client:
            n_workers = len(client.nthreads())
            prepare_workers(client)
            client.run(_warm_up, job)   # imports, Numba's cached kernels, the operator: counted in the start-up
            # the job goes to every worker once, not with every task
            job_on_workers = client.scatter(job, broadcast=True, hash=False)
            startup = time.perf_counter() - t0
            t0 += startup
            # keys carry the run's identity: two recordings on one shared scheduler never share a task
            tag = hashlib.sha256(ident.encode()).hexdigest()[:8]
            for c, res in map_unordered(client, process_chunk, todo, job_on_workers, name=f"frames-{tag}",
                                        progress=progress, total=len(todo)):
                keep(c, res)
    wall = time.perf_counter() - t0
    frames = pd.concat([pd.read_csv(parts / f"chunk-{c:05d}.csv", keep_default_na=False, na_values=[""])
                        for c in range(job.n_chunks)], ignore_index=True).sort_values(["frame", "plane"])
    counts = frames.groupby("frame").size()
    if len(counts) != job.source.n_frames or (counts != len(job.depths_mm)).any():
        raise ValueError(f"{parts} does not hold every frame exactly once; delete it and run again")
    if (frames.failure == NONFINITE_FRAME).all():
        raise ValueError(f"every frame of the recording holds NaN or inf: nothing to measure ({parts})")
    lost = frame_failures(frames)
    if len(lost) == job.source.n_frames:
        raise ValueError(f"no frame of the recording could be processed (frame 0: {lost[0]}): nothing to measure; "
                         f"the frames are in {parts}")
    if truth is not None:
        frames["height_mm_true"] = np.asarray(truth, float)[frames.frame.to_numpy(), frames.plane.to_numpy()]
        frames["height_err_mm"] = frames.height_mm - frames.height_mm_true
    spec, over = recording_spectra(frames, job.fps, nperseg)
    pk = peaks(spec, job.truth_freqs_hz)
    failed = frames.failure.notna().groupby(frames.plane).sum()
    pk["n_failed"] = pk.plane.map(failed).astype(int)
    pk["n_over_exposed"] = len(over)
    _write_csv(out / "frames.csv", frames)
    _write_csv(out / "spectra.csv", spec)
    _write_csv(out / "peaks.csv", pk)
    plot_sequence(out / "sequence.png", frames, spec, pk,
                  f"{job.source.n_frames} frames at {job.fps:g} frames/s, route {job.route}")
    summary = dict(settings=job.identity(), n_frames=job.source.n_frames, chunks_processed=len(todo),
                   workers=n_workers, scheduler=scheduler, startup_s=startup, wall_s=wall,
                   frames_per_s=(len(todo) and sum(min(job.chunk, job.source.n_frames - c * job.chunk)
                                                   for c in todo) / wall),
                   busy_s=busy, failed_frames={int(k): int(v) for k, v in failed.items()},
                   unprocessed_frames={str(k): v for k, v in lost.items()},
                   provenance=provenance())
    if not todo and before.get("chunks_processed"):  # nothing done here: the timings of the run that did it
        summary.update({k: before[k] for k in TIMINGS if k in before},
                       timings="of the run that processed the chunks (a rerun found them all done)")
    if "n_saturated" in frames:
        from ..real.clipping import CLIPPED_WARN
        per_frame = frames.groupby("frame")[["n_saturated", "clipped_share"]].first()
        summary["n_saturated"] = dict(frames=int((per_frame.n_saturated > 0).sum()),
                                      max_per_frame=int(per_frame.n_saturated.max()))
        summary["over_exposed"] = dict(frames=int((per_frame.clipped_share > CLIPPED_WARN).sum()),
                                       max_share=float(per_frame.clipped_share.max()),
                                       clipped_frames=int((per_frame.clipped_share > 0).sum()),
                                       left_out_of_spectra=over)
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=1, default=float))
    return summary
