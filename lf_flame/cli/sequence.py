"""The ``sequence`` and ``simulate-sequence`` commands: a flame recording's per-plane
diagnostics over time and their flicker spectra (:mod:`lf_flame.recordings`), serially or on Dask.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from ..tomo.defaults import ADMM_QUIET, ADMM_TV, DEFAULT_TV, SOLVERS
from .options import AUTO_LEVEL, _level_or_none, add_search_arg, count, positive_int, finite

#: Sensor noise of ``--noise``: full well (e-), read noise (e-), bits (a 12-bit high-speed camera).
NOISE = (10_000.0, 5.0, 12)


def _sequence_of(a, cam):
    from ..simulate.scenes_time import flicker_sequence
    fps = 500.0 if a.fps is None else a.fps
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"--fps must be positive and finite (frames/s). Received: {a.fps:g}")
    return flicker_sequence(cam, np.random.default_rng(a.seed), a.simulate, fps=fps,
                            duration_s=a.duration, freqs_hz=a.freq, noise=NOISE if a.noise else None)


def _check_recording_size(a, cam) -> None:
    """Refuse a recording to render whose frames (16-bit, ``--fps`` x ``--duration`` of them) would not fit on the
    disk that holds ``--out``, before any is rendered: --fps 1e9 had written 1.25 GB in 20 s, on to a full disk."""
    import shutil
    fps = 500.0 if a.fps is None else a.fps
    if not a.duration > 0:
        raise ValueError(f"--duration must be positive (s). Received: {a.duration:g}")
    n = fps * a.duration
    need = n * cam.sensor_shape[0] * cam.sensor_shape[1] * 2
    q = Path(a.out).absolute().parent
    while not q.exists() and q != q.parent:
        q = q.parent
    free = shutil.disk_usage(q).free
    if need > free:
        raise ValueError(f"{n:.3g} frames ({fps:g} frames/s for {a.duration:g} s) of {cam.sensor_shape[0]} x "
                         f"{cam.sensor_shape[1]} px take up to {need / 1e9:.3g} GB; {q} has {free / 1e9:.3g} GB "
                         "free: a lower --fps or a shorter --duration")


def _camera(a):
    from ..optics.camera import PAPER_CAMERA
    path = getattr(a, "camera", None) or getattr(a, "data_config", None)
    if getattr(a, "camera", None) and getattr(a, "data_config", None):
        raise ValueError("give the camera once: --camera or --data-config")
    if path:
        from ._io import camera_config
        return camera_config(path)
    return PAPER_CAMERA


def first_frame_depths(source, camera, calibration=None, sensor=None, search_range=None, images=None):
    """The planes of a recording without given ones: those ``reconstruct --depths auto`` finds in its first frame
    (depths found, the residual searched, the depths of flames one behind another refined:
    :func:`lf_flame.cli.planes.found_planes`, :func:`~lf_flame.cli.planes.solve_found`), the frame decoded with
    ``calibration`` where given (``camera`` the real one, ``sensor`` a colour camera's), searched over
    ``search_range`` (``--search-range``; None: what the camera can refocus), with the white image and dark frame
    ``images`` (:func:`~lf_flame.real.readers.decode_capture`'s). A depth the residual's
    search saw and did not take is warned of (:func:`~lf_flame.cli.planes.possible_warning`). Returns the depths
    (mm) and the :class:`~lf_flame.tomo.depth.FoundDepths` they are."""
    from ..real.lightfield import from_raw
    from ..real.readers import decode_capture
    from ..temperature.mosaic import monochrome_light_field
    from .planes import found_planes, possible_warning, solve_found
    raw = np.asarray(next(iter(source.frames(0, 1))), np.float64)
    # a colour capture's channels levelled into one light field
    lf = monochrome_light_field(from_raw(raw, camera, "the first frame", sensor=sensor) if calibration is None else
                                decode_capture(raw, camera, calibration, sensor, "the first frame", images))
    print("the recording's planes, as reconstruct finds a capture's, in its first frame:")
    try:
        _, _, found = found_planes(lf, search_range=search_range)
        found, _, _ = solve_found(lf, found)
    except ValueError as e:       # a dark or broken first frame: say where the planes were looked for, and the way out
        raise ValueError(f"the recording's first frame, where its planes are found: {e}; give the planes (--depth MM, "
                         "repeatable) or start the recording at a frame with the flames in it") from None
    possible_warning(found)                            # a depth seen, not taken: the --depth planes to give
    return [float(d) for d in found.planes_mm], found


def cmd_simulate_sequence(a):
    from ..recordings.sources import SimulatedSource, write_frames
    from ..simulate.scenes_temperature import FLICKER_K
    cam = _camera(a)
    _check_recording_size(a, cam)
    seq = _sequence_of(a, cam)
    camera_file = getattr(a, "camera", None) or getattr(a, "data_config", None)
    from ..optics.camera_file import load_colour_sensor
    named, sensor = (load_colour_sensor(camera_file) if camera_file else None), None
    if a.colour:
        from ._io import render_sensor
        sensor, where = render_sensor(named, camera_file)
        print(f"colour sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where}): each flame with its "
              "temperature field, its sheath's flickering at the flame's frequency")
    elif named is not None:
        print(f"{camera_file} names a colour sensor ({named.pattern}); the recording is rendered monochrome "
              "and recorded so ('lf-flame sequence' reads it as monochrome; --colour renders it through the mosaic)")
    source = SimulatedSource(seq, cam, a.rays_per_pixel, sensor)
    path = write_frames(a.out, source, progress=not a.quiet)
    temps = [f" sheath {pk:g} K +- {FLICKER_K:g} K" for pk in source.peaks_k] if a.colour else [""] * len(seq.flames)
    print(f"{seq.n_frames} frames at {seq.fps:g} frames/s, flames at "
          + ", ".join(f"{f.depth_offset_mm:+g} mm {f.freq_hz:g} Hz{t}" for f, t in zip(seq.flames, temps))
          + f" -> {path}")
    note = clipped_frames_note(path)
    if note:
        print(note)


def clipped_frames_note(path):
    """A note on the frames of a recording ``simulate-sequence`` wrote (``frames``, uint16) that clip the sensor (a
    pixel at full scale, 65535: where flames one behind another add up), or None where none does."""
    import h5py
    with h5py.File(path, "r") as f:
        d = f["frames"]
        full = np.iinfo(d.dtype).max
        counts = [int(np.count_nonzero(d[i] == full)) for i in range(d.shape[0])]
    clipped = [c for c in counts if c]
    if not clipped:
        return None
    return (f"note: {len(clipped)} of {len(counts)} frames clip the sensor ({min(clipped)}-{max(clipped)} pixels at "
            "full scale): 'lf-flame sequence' leaves their samples out of the fit, and warns where they are many")


def cmd_sequence(a):
    from ..simulate.scenes_time import FlameSequence
    from ..recordings.job import SequenceJob, sequence_truth, simulated_job
    from ..recordings.sources import SimulatedSource, open_source, source_frame_rate
    from ..recordings.runner import run
    if (a.input is None) == (a.simulate is None):
        raise ValueError("give a recording INPUT or --simulate KIND, not both or neither")
    cam, seq, attrs = _camera(a), None, {}
    if a.simulate:
        seq = _sequence_of(a, cam)
        source = SimulatedSource(seq, cam, a.rays_per_pixel)
        fps = seq.fps
    else:
        source, attrs = open_source(a.input)
        if "camera" in attrs:
            from ..optics.camera import PlenopticCamera
            from ..config import stored_json
            stored = PlenopticCamera.from_dict(stored_json(attrs["camera"], a.input, "camera"))
            if a.data_config or a.camera:
                from ..real.readers import stored_camera_warning
                stored_camera_warning(cam, stored, str(a.input))
            else:
                cam = stored
        fps = source_frame_rate(source, attrs, a.fps)
        if "sequence" in attrs:
            from ..config import stored_json
            seq = FlameSequence.from_dict(stored_json(attrs["sequence"], a.input, "sequence"))
    if a.depth and a.slope:
        raise ValueError("give the planes as --depth or as --slope, not both")
    knobs = dict(iters=a.iters, tv=a.tv, saturation=a.saturation, operator_rays=a.operator_rays)
    if seq is not None and not (a.depth or a.slope):
        print("planes at the simulated recording's flames' depths (plane 0 the farthest): "
              + ", ".join(f"{f.depth_offset_mm:+.2f}" for f in seq.flames) + " mm (--depth to choose others)")
    if not (a.calibration or cam.perfect_grid):
        raise ValueError("the frames are a camera's whose lenslet grid is not a perfect one (rotated, hexagonal, or "
                         "lenslet images no whole number of pixels apart): give its white image's --calibration "
                         "('lf-flame calibrate'), with which each frame is decoded")
    # a colour camera (its camera file's [sensor] cfa, else the recording's record): each frame's channels
    # apart, levelled into one light field
    from ..real.readers import capture_sensor
    colour = capture_sensor(a.camera or None, attrs, str(a.input))[0] if a.input else None
    if seq is not None and colour is None and not a.depth and not a.calibration:
        if a.slope and len(a.slope) != len(seq.flames):
            raise ValueError(f"give one --slope per flame ({len(seq.flames)}). Received: {a.slope}")
        job, truth = simulated_job(seq, cam, source, route=a.route, chunk=a.chunk, slopes=a.slope, **knobs)
    else:
        truth = None
        if seq is not None and not (a.depth or a.slope):     # a simulated recording decoded, or in colour: its flames
            a.depth = [f.depth_offset_mm for f in seq.flames]
            knobs["truth_freqs_hz"], truth = sequence_truth(seq)
        cal, k, sensor, calibration, real = None, 1, None, None, cam
        if colour is not None:
            sensor = colour.record()
            print(f"colour sensor {colour.name}, {colour.pattern} phase {colour.phase}: each frame's red and "
                  "green samples levelled into one light field (blue left out)")
        white, dark = a.white, a.dark
        if a.calibration:                # real frames: the planes are the decoded views' camera's
            from ..real.calibration import GridCalibration
            from ..real.images import calibration_image_path
            calibration = GridCalibration.load(a.calibration)
            assumed = " (no camera file given, and the recording stores none: the paper's camera was taken; give " \
                "the frames' --camera cam.toml)" if not (a.data_config or a.camera or "camera" in attrs) else ""
            if assumed and tuple(calibration.sensor_shape) != tuple(cam.sensor_shape):
                raise ValueError(f"the white-image calibration's images are {calibration.sensor_shape[0]} x "
                                 f"{calibration.sensor_shape[1]} px, the camera's sensor {cam.sensor_shape[0]} x "
                                 f"{cam.sensor_shape[1]} px{assumed}")
            from ..real.own_camera import decoded_views_camera
            try:
                cal, cam, k = calibration.to_dict(), *decoded_views_camera(cam, calibration, colour is not None)
            except ValueError as e:
                if not assumed:
                    raise
                raise ValueError(f"{e}{assumed}") from None
            # as decode: the calibration's white image and dark frame unless others are given
            white = None if a.no_white else calibration_image_path(calibration.white, "white", a.white)
            dark = calibration_image_path(calibration.dark, "dark", a.dark)
        if a.depth or a.slope:
            depths = [float(v) for v in a.depth] if a.depth else [cam.depth_for_slope(s) for s in a.slope]
        else:                            # the depths found in the first frame, as reconstruct finds a capture's
            from ..real.images import decoding_images
            depths, found = first_frame_depths(source, real, calibration, colour, a.search_range,
                                               decoding_images(white, dark) if calibration else None)
            if a.route == "reconstruct-admm":
                # near planes held to their own regions where they meet, as reconstruct holds them
                from ..tomo.found_planes import found_support
                knobs["support"] = found_support(found, cam)
        slopes = list(a.slope) if a.slope else [cam.slope_for_depth(d) for d in depths]
        from .planes import check_planes
        check_planes(cam, depths)
        job = SequenceJob(source, cam, fps, tuple(depths), tuple(slopes), (None,) * len(depths), a.route,
                          cal, white, dark, chunk=a.chunk, bin_views=k, sensor=sensor, **knobs)
    if seq is None:                      # real frames: a black level left in, read in the first frame
        from ._io import black_level_warning
        black_level_warning(job.unlit_level(source.raw(0)))
    s = run(job, a.out, scheduler=a.scheduler, workers=a.workers, nperseg=a.nperseg, truth=truth,
            progress=not a.quiet)
    import pandas as pd
    from ..recordings.flicker import unresolved_note
    pk = pd.read_csv(f"{a.out}/peaks.csv")
    print(pk.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    note = unresolved_note(pk)
    if note:
        print(note)
    lost = s.get("unprocessed_frames") or {}
    for f, why in list(lost.items())[:3]:
        print(f"frame {f}: {why}")
    if len(lost) > 3:
        print(f"... and {len(lost) - 3} more frames not processed (their rows in {a.out}/frames.csv say why)")
    for k, n in s["failed_frames"].items():
        if n:
            print(f"plane {k}: {n} of {s['n_frames']} frames could not be measured (the plane's mean in its spectrum)")
    if "n_saturated" in s:
        from .real import overexposure_warning
        over = s["over_exposed"]
        if over["clipped_frames"]:
            print(f"{over['clipped_frames']} of {s['n_frames']} frames clip the sensor, their clipped pixels left out "
                  f"of the fit (up to {100 * over['max_share']:.3g} % of a frame's lit pixels; frames.csv: "
                  "clipped_share)")
        overexposure_warning(over["max_share"], f"in {over['frames']} of {s['n_frames']} frames up to ")
        if over["left_out_of_spectra"]:
            left = over["left_out_of_spectra"]
            shown = ", ".join(map(str, left[:10])) + (", ..." if len(left) > 10 else "")
            print(f"frames over-exposed against the rest ({shown}): their heights and intensities are in frames.csv, "
                  "and the spectra take each plane's mean there")
    n = s["chunks_processed"]
    done = (f"every chunk done before: {n} chunk{'s' * (n != 1)} processed then, at {s['frames_per_s']:.1f} frames/s"
            if s.get("timings") else f"{n} chunk{'s' * (n != 1)} processed, {s['frames_per_s']:.1f} frames/s")
    print(f"{s['n_frames']} frames ({done}) -> {Path(a.out) / 'frames.csv'}, spectra.csv, peaks.csv, sequence.png, "
          "summary.json")


def _sequence_scene_args(s, simulate_only=False):
    """Arguments of a simulated recording (``simulate-sequence``; ``sequence --simulate``)."""
    pre = "--simulate: " if simulate_only else ""
    if not simulate_only:
        s.add_argument("--simulate", choices=["paper", "overlap"], default="paper",
                       help="paper: four flames at the paper's depths; overlap: two flames 20 mm apart, one "
                            "behind the other (another camera: the depths of the same parallax)")
    s.add_argument("--fps", type=finite, help=("frame rate, frames/s (a recording: default its file's; " if
                                              simulate_only else "frame rate, frames/s (") + "simulated: 500)")
    s.add_argument("--duration", type=finite, default=1.0, help=pre + "length, s")
    s.add_argument("--freq", type=finite, action="append", help=pre + "each flame's flicker frequency, Hz, farthest "
                   "first (repeatable; default drawn from 5-20 Hz)")
    s.add_argument("--noise", action="store_true", help=pre + "shot and read noise, 12 bits")
    s.add_argument("--seed", type=count, default=0, help=pre + "seed of the frequencies, phases and jitter")
    s.add_argument("--rays-per-pixel", type=int, default=4, help=pre + "rays traced per sensor pixel")
    s.add_argument("--camera", help="camera file (TOML: the datasheet tables of docs/own_camera.md, or a [camera] "
                   "table; default: " + ("the file's, else the paper's camera); with --calibration, the camera the "
                                         "frames were taken with" if simulate_only else "the paper's camera)"))
    s.add_argument("--data-config", help="TOML with a [camera] table (as --camera)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")


def add_parsers(sub) -> None:
    """Add ``simulate-sequence`` and ``sequence`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("simulate-sequence", help="render a simulated recording of flickering flames to HDF5 "
                       "(frames (T, H, W), fps, camera and the truth)")
    _sequence_scene_args(s)
    s.add_argument("--colour", action="store_true", help="each flame with its temperature field (its sheath "
                   "flickering at the flame's frequency), through the colour sensor of the camera file's [sensor] "
                   "cfa (else RGGB): a recording for 'lf-flame temperature'")
    s.add_argument("--out", required=True, help="HDF5 file")
    s.set_defaults(func=cmd_simulate_sequence)

    s = sub.add_parser("sequence", help="a flame recording: each plane's height, widths and intensity over time, "
                       "their spectra and dominant flicker frequency (serially or on Dask)")
    s.add_argument("input", nargs="?", help="HDF5 stack of raw frames (dataset 'frames' (T, H, W); optional "
                   "'times_s'), a multi-page TIFF (a high-speed camera's or ImageJ's stack: one frame per page; the "
                   "frame rate from its ImageJ frame interval, else --fps), or a folder of TIFF/PNG/.npy frames in "
                   "the order of the numbers in their names (frame_2 before frame_10)")
    s.add_argument("--simulate", choices=["paper", "overlap"], help="instead of INPUT: a simulated recording, "
                   "rendered frame by frame in the workers")
    _sequence_scene_args(s, simulate_only=True)
    s.add_argument("--depth", type=finite, action="append", help="plane depth offset, mm (repeatable); default: a "
                   "simulated recording's flames' depths, else the depths found in the first frame, as 'reconstruct' "
                   "finds a capture's")
    s.add_argument("--slope", type=finite, action="append", help="plane slope, lenslets per view (repeatable)")
    s.add_argument("--route", choices=["shift-sum", *(f"reconstruct-{k}" for k in SOLVERS)],
                   default="reconstruct-admm",
                   help="each plane's emission (as lf-flame reconstruct, admm by default; its settings: --iters, "
                        "--tv, --saturation, --operator-rays), or the planes refocused by shift-and-sum (faster; "
                        "a plane's flame blurred by its neighbours' light: heights and flicker less sure)")
    s.add_argument("--iters", type=positive_int, help="reconstruct-*: iterations, >= 1 (default: the solver's, as "
                   "lf-flame reconstruct's --iters)")
    s.add_argument("--tv", type=finite, default=None,
                   help=f"reconstruct-pd-tv / -admm: TV weight (default: pd-tv {DEFAULT_TV}; admm by each frame's "
                        f"noise: {ADMM_QUIET['tv']} on quiet data, {ADMM_TV} on noisy)")
    s.add_argument("--saturation", type=_level_or_none, default="auto",
                   help="reconstruct-*: the sensor's clipping level in the views' units: pixels at or above it are "
                        "left out of the fit, counted per frame as n_saturated ('none': fit every pixel; default "
                        "auto, per frame: " + AUTO_LEVEL + ")")
    s.add_argument("--operator-rays", type=int, default=None,
                   help="reconstruct-*: rays per pixel of a traced forward operator (default: the exact operator "
                        "where the camera is a perfect lenslet grid, else 4 rays)")
    s.add_argument("--calibration", help="real frames: JSON of 'lf-flame calibrate' (frames are decoded)")
    s.add_argument("--white", help="real frames: white image for decoding (default: the calibration's, checked by its "
                   "SHA-256), read in the frames' units (an integer file scaled by its type's range, as the frames)")
    s.add_argument("--no-white", action="store_true", help="real frames: no white-image normalisation")
    s.add_argument("--dark", help="real frames: dark frame (default: the calibration's, if it has one)")
    s.add_argument("--nperseg", type=int, help="Welch segment, frames (default: the whole record, bin 1/T)")
    s.add_argument("--chunk", type=int, default=16, help="frames per task (default: %(default)s)")
    s.add_argument("--workers", type=positive_int, help="a local Dask cluster of this many single-thread worker "
                   "processes, >= 1 (default: serial, Numba's threads)")
    s.add_argument("--scheduler", help="an existing Dask cluster: address (tcp://...) or scheduler file")
    s.add_argument("--out", required=True, help="output folder (resumed when it holds the same run)")
    s.set_defaults(out_is_folder=True)
    add_search_arg(s)
    s.set_defaults(func=cmd_sequence)
