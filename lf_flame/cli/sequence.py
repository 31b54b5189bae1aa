"""The ``sequence`` and ``simulate-sequence`` commands: a flame recording's per-plane
diagnostics over time and their flicker spectra (:mod:`lf_flame.sequence`), serially or on Dask.
"""
from __future__ import annotations

import json

import numpy as np

#: Sensor noise of ``--noise``: full well (e-), read noise (e-), bits (a 12-bit high-speed camera).
NOISE = (10_000.0, 5.0, 12)


def _sequence_of(a, cam):
    from ..scenes import flicker_sequence
    return flicker_sequence(cam, np.random.default_rng(a.seed), a.simulate, fps=a.fps or 500.0,
                            duration_s=a.duration, freqs_hz=a.freq, noise=NOISE if a.noise else None)


def _camera(a):
    from ..camera import PAPER_CAMERA
    if getattr(a, "data_config", None):
        from ..config import load_data_config
        return load_data_config(a.data_config)[0]
    return PAPER_CAMERA


def cmd_simulate_sequence(a):
    from ..sequence import SimulatedSource, write_frames
    cam = _camera(a)
    seq = _sequence_of(a, cam)
    path = write_frames(a.out, SimulatedSource(seq, cam, a.rays_per_pixel), progress=not a.quiet)
    print(f"{seq.n_frames} frames at {seq.fps:g} frames/s, flames at "
          + ", ".join(f"{f.depth_offset_mm:+g} mm {f.freq_hz:g} Hz" for f in seq.flames) + f" -> {path}")


def _truth(seq, cam, n_planes):
    """True heights (T, P), frequencies and column bands of a simulated sequence's flames."""
    if len(seq.flames) != n_planes:
        return None, None, [None] * n_planes
    truth = np.array([seq.heights_mm(i) for i in range(seq.n_frames)])
    cols = [(max(0, o["roi"][2] - 2), min(cam.n_cols, o["roi"][3] + 2)) for o in seq.scene(cam, 0).objects]
    return truth, tuple(f.freq_hz for f in seq.flames), cols


def cmd_sequence(a):
    from ..scenes import FlameSequence
    from ..sequence import SequenceJob, SimulatedSource, frame_rate, open_source, run
    if (a.input is None) == (a.simulate is None):
        raise ValueError("give a recording INPUT or --simulate KIND, not both or neither")
    cam, seq, attrs = _camera(a), None, {}
    if a.simulate:
        seq = _sequence_of(a, cam)
        source = SimulatedSource(seq, cam, a.rays_per_pixel)
        fps = seq.fps
    else:
        source, attrs = open_source(a.input)
        times = None
        if "camera" in attrs and not a.data_config:
            from ..camera import PlenopticCamera
            cam = PlenopticCamera.from_dict(json.loads(attrs["camera"]))
        if hasattr(source, "path"):
            import h5py
            with h5py.File(source.path, "r") as f:
                times = f["times_s"][:] if "times_s" in f else None
        fps = frame_rate(a.fps, attrs, times)
        if "sequence" in attrs:
            seq = FlameSequence.from_dict(json.loads(attrs["sequence"]))
    if a.depth and a.slope:
        raise ValueError("give the planes as --depth or as --slope, not both")
    if a.depth:
        depths = [float(v) for v in a.depth]
    elif a.slope:
        depths = [cam.depth_for_slope(s) for s in a.slope]
    elif seq is not None:
        depths = [f.depth_offset_mm for f in seq.flames]
    else:
        raise ValueError("give the planes of a recording: --depth MM (repeatable) or --slope S")
    slopes = list(a.slope) if a.slope else [cam.slope_for_depth(d) for d in depths]
    truth, freqs, cols = _truth(seq, cam, len(depths)) if seq is not None else (None, None, [None] * len(depths))
    cal = None
    if a.calibration:
        from ..calibrate import GridCalibration
        cal = GridCalibration.load(a.calibration).to_dict()
    job = SequenceJob(source, cam, fps, tuple(depths), tuple(slopes), tuple(cols), a.route, cal, a.white, a.dark,
                      freqs, a.chunk)
    s = run(job, a.out, scheduler=a.scheduler, workers=a.workers, nperseg=a.nperseg, truth=truth,
            progress=not a.quiet)
    import pandas as pd
    pk = pd.read_csv(f"{a.out}/peaks.csv")
    print(pk.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"{s['n_frames']} frames ({s['chunks_processed']} chunks processed, {s['frames_per_s']:.1f} frames/s) "
          f"-> {a.out}/frames.csv, spectra.csv, peaks.csv, sequence.png, summary.json")
