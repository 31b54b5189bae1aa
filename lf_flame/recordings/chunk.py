"""The processing of one chunk of a recording's frames (:class:`~lf_flame.recordings.job.SequenceJob`).

Every frame is refocused at the planes (or reconstructed, :mod:`lf_flame.tomo`) and
measured per plane by :func:`lf_flame.measure.diagnostics.measure_flame`; a frame that cannot be processed is a
failed row per plane, and the others go on.
"""
from __future__ import annotations

import time

import numpy as np

from .job import NONFINITE_FRAME, SequenceJob


def _warm_up(job: SequenceJob) -> None:
    """Process frame 0 once (imports, Numba's kernels loaded, the emission operator built):
    a worker's first task then costs what every other does."""
    _process_frames(job, 0, 1)


def process_chunk(c: int, job: SequenceJob) -> dict:
    """Process chunk ``c`` of ``job`` (frames ``c * chunk`` to ``(c + 1) * chunk``), its
    frames read from the source in one call (:meth:`H5Source.frames`: one open).

    Returns
    -------
    dict with ``rows`` (one dict per frame and plane: frame, time_s, plane, depth_mm,
    :meth:`FlameMeasurement.summary` fields, failure; on ``reconstruct-*`` routes ``n_saturated``, the frame's
    view samples left out of the fit (clipped; a decoded frame's dark rim too), and ``clipped_share``, its clipped
    pixels' share of the lit ones) and the seconds spent reading (or rendering), refocusing and measuring.

    A folder's frame that cannot be read (a truncated file, a missing one:
    :func:`lf_flame.recordings.sources.tolerant_frames`), or one written only in part (its last rows 0 where the
    chunk's frame before holds light, :func:`truncated_rows`), gets a row per plane with :data:`UNPROCESSED_FRAME`
    and why. A frame that holds NaN or inf (a corrupt read, a dropped packet) gets a row per plane with
    :data:`NONFINITE_FRAME` as its failure, and the frames after it go on (an admm chunk's next frame
    continues the solve before it). A frame that cannot be processed otherwise (another sensor size, every sample
    clipped, views without structure: a uniform frame, :func:`lf_flame.real.black_level.view_spread`, a solve that
    gave NaN or inf planes) gets a row per plane with
    :data:`UNPROCESSED_FRAME` and the reason as its failure, and the frames after it go on (an admm chunk's next
    frame solved from scratch); :func:`lf_flame.recordings.runner.run` refuses a recording whose every frame failed.
    """
    return _process_frames(job, c * job.chunk, min((c + 1) * job.chunk, job.source.n_frames))


#: A frame whose last rows, at least this share of its height, read 0 where the frame before holds light is a frame
#: written only in part (:func:`truncated_rows`): a user's frame with its lower half 0 had been measured as any other,
#: heights 2-3 mm short, no flag.
TRUNCATED_ROWS = 0.05


def truncated_rows(raw: np.ndarray, before: np.ndarray | None) -> int:
    """How many of a frame's last rows read exactly 0 where the frame ``before`` it holds light (above a tenth of its
    99.9th percentile), where they are at least :data:`TRUNCATED_ROWS` of its height; else 0 (also for a frame black
    throughout, without a frame before, or one of another shape).

    Parameters
    ----------
    raw, before : ndarray of shape (H, W), or None for ``before``

    Returns
    -------
    int
    """
    if before is None or np.shape(before) != np.shape(raw) or np.ndim(raw) != 2:
        return 0
    zero = ~np.any(np.asarray(raw) != 0, axis=1)
    if zero.all():                               # a black frame is a frame (the flame out, the shutter shut)
        return 0
    n = int(np.argmin(zero[::-1]))               # trailing rows that read 0 throughout
    if n < max(1, TRUNCATED_ROWS * len(zero)):
        return 0
    b = np.asarray(before, np.float64)
    top = np.percentile(b, 99.9)
    return n if top > 0 and np.any(b[-n:] > 0.1 * top) else 0


#: The start of the failure of every plane of a frame that could not be processed otherwise (another size, every
#: sample clipped, a solve that gave NaN), followed by the reason (:func:`process_chunk`).
UNPROCESSED_FRAME = "frame not processed"


def _process_frames(job: SequenceJob, start: int, stop: int) -> dict:
    from ..measure.diagnostics import EmptyPlaneError, measure_flame
    from ..real.black_level import FLAT_SPREAD, view_spread
    from ..routes import measure_settings
    kw = measure_settings(job.route)
    t = dict(read_s=0.0, refocus_s=0.0, measure_s=0.0)
    rows = []
    state = {}                                   # admm: the solve carried from frame to frame within the chunk
    previous = None                              # the chunk's frame before (a chunk's first has none here)
    from .sources import tolerant_frames
    raws = tolerant_frames(job.source, start, stop)
    for i in range(start, stop):
        t0 = time.perf_counter()
        raw = next(raws)
        t1 = time.perf_counter()
        t["read_s"] += t1 - t0
        if isinstance(raw, Exception):           # a file that cannot be read: this frame alone fails
            state.clear()
            rows += [dict(frame=i, time_s=i / job.fps, plane=k, depth_mm=d, failure=f"{UNPROCESSED_FRAME}: {raw}")
                     for k, d in enumerate(job.depths_mm)]
            continue
        if not np.all(np.isfinite(raw)):
            rows += [dict(frame=i, time_s=i / job.fps, plane=k, depth_mm=d, failure=NONFINITE_FRAME)
                     for k, d in enumerate(job.depths_mm)]
            continue
        before, previous = previous, raw
        try:
            cut = truncated_rows(raw, before)
            if cut:
                raise ValueError(f"its last {cut} rows read 0 where the frame before holds light: a frame written only "
                                 "in part (a dropped transfer)")
            views, clipped = job.frame(raw)
            spread = view_spread(job._square(views))
            if spread is not None and spread < FLAT_SPREAD:
                lo, hi = float(np.min(raw)), float(np.max(raw))
                one = "" if lo != hi else f"; every pixel reads {hi:.4g}" + (" (full scale: over-exposed)" * (hi == 1))
                raise ValueError(f"its views carry no structure (each varies by {spread:.2g} of its level across its "
                                 f"lenslets, under {FLAT_SPREAD:g}{one}): a uniform frame (a glare, a blank or washed-"
                                 "out frame) holds no flame to measure")
            stack, n_sat = job.planes_and_saturated(views, state, clipped,
                                                    job.unit(raw) if job.solver is not None else None)
            if not np.all(np.isfinite(stack)):
                dark = "; the frame holds no light" if not np.any(raw > 0) else ""
                raise ValueError(f"the {job.solver or 'refocused'} planes hold NaN or inf{dark}")
        except ValueError as e:                  # this frame alone: a failed row per plane, the others go on
            state.clear()                        # admm: the next frame is solved from scratch
            rows += [dict(frame=i, time_s=i / job.fps, plane=k, depth_mm=d, failure=f"{UNPROCESSED_FRAME}: {e}")
                     for k, d in enumerate(job.depths_mm)]
            continue
        t2 = time.perf_counter()
        extra = {} if n_sat is None else dict(n_saturated=n_sat, clipped_share=job.clipped_share(raw))
        for k, (plane, d) in enumerate(zip(stack, job.depths_mm)):
            row = dict(frame=i, time_s=i / job.fps, plane=k, depth_mm=d, **extra)
            try:
                row.update(measure_flame(plane, job.camera, d, columns=job.columns[k], **kw).summary(), failure="")
            except EmptyPlaneError as e:
                row.update(failure=str(e))
            rows.append(row)
        t3 = time.perf_counter()
        t["refocus_s"] += t2 - t1
        t["measure_s"] += t3 - t2
    return dict(rows=rows, **t)
