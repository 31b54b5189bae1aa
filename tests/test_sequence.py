"""Flame recordings (issues 26, 34): per-plane flicker frequencies, the Dask path against the
serial one (one local cluster of two 2-thread workers for the module), a real multi-process
cluster with a worker killed mid-run, resuming, the reconstruction's settings, and the bad
inputs a user meets."""
import argparse
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.cli import main
from lf_flame.simulate.scenes_time import flicker_sequence
from lf_flame.recordings.sources import SimulatedSource, frame_rate, numbered_gaps, open_source, write_frames
from lf_flame.recordings import job as job_module
from lf_flame.recordings.flicker import peaks, spectra, unresolved_note
from lf_flame.recordings.chunk import process_chunk
from lf_flame.recordings.job import simulated_job
from lf_flame.recordings.runner import run

NOISE = (10_000.0, 5.0, 12)


def _job(seq, chunk=16, source=None):
    return simulated_job(seq, PAPER_CAMERA, source, chunk=chunk)[0]


def _truth(seq):
    return simulated_job(seq, PAPER_CAMERA)[1]


@pytest.mark.parametrize("noise", [None, NOISE], ids=["noise-free", "noise"])
def test_each_plane_flickers_at_its_own_flames_frequency(tmp_path, noise):
    """Four flames at the paper's depths, 5-20 Hz, 1 s at 100 frames/s: each plane's height
    spectrum peaks within one bin (1 Hz) of its flame's frequency, and the heights follow
    the truth frame by frame."""
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(11), "paper", fps=100, duration_s=1.0, noise=noise)
    run(_job(seq), tmp_path, truth=_truth(seq), progress=False)
    pk = pd.read_csv(tmp_path / "peaks.csv").query("signal == 'height_mm'")
    assert len(pk) == 4 and pk.within_one_bin.all(), pk
    assert (pk.others_below_db > 10).all(), pk
    frames = pd.read_csv(tmp_path / "frames.csv")
    assert frames.height_err_mm.abs().quantile(0.9) < 0.5
    assert json.loads((tmp_path / "summary.json").read_text())["n_frames"] == 100


def test_a_record_shorter_than_two_periods_does_not_resolve_its_flicker():
    """A 10 Hz flicker over 20 frames at 500 frames/s (0.04 s, 25 Hz bins) peaks in the spectrum's first bin: not
    resolved, not 'within one bin' of its 10 Hz, and the note says what record resolves it; over 1 s at 100 frames/s
    the same flicker is resolved at 10 Hz. (The short record's every plane read 25 Hz, within one bin of 5-20 Hz.)"""
    def table(fps, n):
        t = np.arange(n) / fps
        return pd.DataFrame(dict(frame=np.arange(n), plane=0, depth_mm=0.0, height_mm=10 + np.sin(2 * np.pi * 10 * t),
                                 integrated_intensity=1.0 + 0.1 * np.sin(2 * np.pi * 10 * t)))
    short = peaks(spectra(table(500.0, 20), 500.0), [10.0])
    assert (short.dominant_hz == 25).all() and not short.resolved.any() and not short.within_one_bin.any()
    note = unresolved_note(short)
    assert "2 of 2 dominant frequencies are not resolved" in note and "0.04 s" in note and "2/f s" in note
    long = peaks(spectra(table(100.0, 100), 100.0), [10.0])
    assert (long.dominant_hz == 10).all() and long.resolved.all() and long.within_one_bin.all()
    assert (long.periods == 10).all() and unresolved_note(long) is None


def test_frequencies_are_distinct_and_clear_of_harmonics():
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "paper")
    f = [fl.freq_hz for fl in seq.flames]
    assert all(5 <= v <= 20 for v in f)
    assert all(abs(a - b) >= 2 and abs(2 * a - b) >= 2 for i, a in enumerate(f) for j, b in enumerate(f) if i != j)
    with pytest.raises(ValueError, match="second harmonic"):
        flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "paper", fps=30)
    with pytest.raises(ValueError, match="frequencies"):
        flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "overlap", freqs_hz=[8.0])


FAR_CAMERA = """[main_lens]
focal_length_mm = 100.0
f_number = 4.0
focus_distance_mm = 2000.0

[microlens_array]
pitch_um = 125.0
focal_length_mm = 0.5

[sensor]
pixel_size_um = 5.5
rows = 1200
cols = 900
"""


def test_another_cameras_recording_keeps_the_paper_flames_parallax(tmp_path):
    """A recording of a camera focused at 2 m (22 views of 52 x 39 lenslets): its flames stand where their
    slopes are the paper camera's times the factor ``simulate --scene depth`` carries its depths by (shrunk
    alike to fit the camera's range), in order and within that range; at the paper's millimetres the four
    lay within 0.01 lenslet per view of each other. The paper's camera keeps its depths to the last digit."""
    from lf_flame.cli._io import camera_config
    from lf_flame.simulate.scenes import PAPER_DEPTHS_MM
    from lf_flame.simulate.scenes_depth import camera_depth_ranges
    for kind, mm in (("paper", PAPER_DEPTHS_MM), ("overlap", (10.0, -10.0))):
        seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), kind)
        assert tuple(f.depth_offset_mm for f in seq.flames) == tuple(mm)
    (tmp_path / "far.toml").write_text(FAR_CAMERA)
    cam = camera_config(str(tmp_path / "far.toml"))
    assert np.ptp([cam.slope_for_depth(d) for d in PAPER_DEPTHS_MM]) < 0.01
    seq = flicker_sequence(cam, np.random.default_rng(3), "paper")
    depths = [f.depth_offset_mm for f in seq.flames]
    slopes = np.array([cam.slope_for_depth(d) for d in depths])
    paper = np.array([PAPER_CAMERA.slope_for_depth(d) for d in PAPER_DEPTHS_MM])
    lo, hi = camera_depth_ranges(cam)["depth_range"]
    assert all(lo - 1e-6 <= d <= hi + 1e-6 for d in depths) and np.all(np.diff(depths) < 0)   # farthest first
    ratio = slopes[paper != 0] / paper[paper != 0]
    assert np.allclose(ratio, ratio[0], rtol=1e-4) and 0 < ratio[0] <= min(14 / 21, 39 / 90) + 1e-9
    assert np.ptp(slopes) > 0.1                       # about 2 lenslets of parallax across its 22 views


@pytest.fixture(scope="module")
def small_seq():
    """A short recording: 40 frames, chunks of 4."""
    return flicker_sequence(PAPER_CAMERA, np.random.default_rng(5), "overlap", fps=100, duration_s=0.4)


@pytest.fixture(scope="module")
def serial_table(small_seq, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    run(_job(small_seq, chunk=4), out, progress=False)
    return (out / "frames.csv").read_bytes()


@pytest.fixture(scope="module")
def cluster():
    """One local cluster for the module: two worker processes of two threads each."""
    from distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=2, processes=True, dashboard_address=":0") as lc, \
            Client(lc) as client:
        yield lc.scheduler_address, client


def test_the_dask_path_writes_the_serial_tables(small_seq, serial_table, cluster, tmp_path):
    """On workers of two threads each (two chunks at once in one process)."""
    s = run(_job(small_seq, chunk=4), tmp_path, scheduler=cluster[0], progress=False)
    assert s["workers"] == 2
    assert (tmp_path / "frames.csv").read_bytes() == serial_table


def _kernel_threads(item):
    """A task: run a parallel Numba kernel; the kernel threads and threading layer it had."""
    import numba
    from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack
    focal_stack(np.ones((3, 3, 16, 16), np.float32), [0.0, 0.5], aperture_mask(3, "circular"))
    time.sleep(0.2)   # the worker's two threads overlap
    return numba.get_num_threads(), numba.threading_layer()


def test_tasks_on_a_two_thread_worker_run_their_kernels_on_one_thread(cluster):
    """A worker of two threads runs two tasks at once: each task's kernels get one thread
    (not the worker's two, 4 threads on 2 cores), on a layer that takes concurrent kernels."""
    import cloudpickle
    from lf_flame.parallel import map_unordered
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        got = dict(map_unordered(cluster[1], _kernel_threads, range(8), name="threads", progress=False))
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert sorted(got) == list(range(8))
    assert {n for n, _ in got.values()} == {1}, got
    assert {layer for _, layer in got.values()} <= {"omp", "tbb"}, got


def test_each_worker_builds_the_emission_operator_once(cluster, tmp_path):
    """8 chunks of one frame on 2 workers, reconstructed: each worker builds the operator
    (and its ray record) once, in the warm-up, not once per chunk; the frames carry the
    count of saturated pixels."""
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(7), "overlap", fps=100, duration_s=0.08)
    job = simulated_job(seq, PAPER_CAMERA, route="reconstruct-adjoint", chunk=1, operator_rays=1)[0]

    def builds():
        return sum(cluster[1].run(lambda: job_module._OPERATOR["builds"]).values())
    before = builds()
    s = run(job, tmp_path, scheduler=cluster[0], progress=False)
    assert s["chunks_processed"] == 8 == seq.n_frames
    assert builds() - before <= 2
    assert "n_saturated" in pd.read_csv(tmp_path / "frames.csv")


def _dask_cli():
    exe = Path(sys.executable).with_name("dask")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]


def _wait_for(cond, what, timeout_s=120.0):
    t = time.monotonic()
    while not cond():
        assert time.monotonic() - t < timeout_s, f"waited {timeout_s:g} s for {what}"
        time.sleep(0.02)


def test_a_killed_worker_loses_and_duplicates_no_frame(small_seq, serial_table, tmp_path):
    """A real cluster over TCP (``dask scheduler`` and two ``dask worker`` processes, no
    nanny): one worker is killed with SIGKILL while it holds a chunk and chunks are still
    to do; the scheduler records the chunk it lost; the run completes, every frame once,
    the same table as the serial path."""
    sf = tmp_path / "scheduler.json"
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    procs = [subprocess.Popen([*_dask_cli(), "scheduler", "--scheduler-file", str(sf), "--port", "0",
                               "--no-dashboard", "--host", "127.0.0.1"], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        for _ in range(300):
            if sf.exists():
                break
            time.sleep(0.1)
        for _ in range(2):
            procs.append(subprocess.Popen([*_dask_cli(), "worker", "--scheduler-file", str(sf), "--nthreads", "1",
                                           "--no-nanny", "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL))
        from distributed import Client
        c = Client(scheduler_file=str(sf), timeout=60)
        c.wait_for_workers(2, timeout=120)
        victim = {pid: addr for addr, pid in c.run(os.getpid).items()}[procs[1].pid]
        job = _job(small_seq, chunk=4)   # 10 chunks of 4 frames
        out = tmp_path / "run"
        result = {}
        th = threading.Thread(target=lambda: result.update(s=run(job, out, scheduler=str(sf), progress=False)))
        th.start()
        _wait_for(lambda: len(list((out / "parts").glob("chunk-*.csv"))) >= 2, "two chunks done")
        _wait_for(lambda: any(k.startswith("frames-") for k in c.processing([victim]).get(victim, ())),
                  "a chunk on the worker to kill")
        done_at_kill = len(list((out / "parts").glob("chunk-*.csv")))
        procs[1].send_signal(signal.SIGKILL)
        th.join(timeout=300)
        assert not th.is_alive()
        assert done_at_kill < job.n_chunks, "the run ended before the worker was killed"
        assert procs[1].wait(timeout=10) == -signal.SIGKILL
        removed = [e for _, e in c.get_events(victim) if e.get("action") == "remove-worker"]
        assert removed and any(str(k).startswith("frames-") for k in removed[0]["processing-tasks"]), removed
        c.close()
        assert result["s"]["chunks_processed"] == job.n_chunks
        frames = pd.read_csv(out / "frames.csv")
        assert sorted(frames.frame) == sorted(list(range(small_seq.n_frames)) * 2)
        assert (out / "frames.csv").read_bytes() == serial_table
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_a_restart_skips_the_chunks_done(small_seq, serial_table, tmp_path):
    job = _job(small_seq, chunk=4)
    run(job, tmp_path, progress=False)
    (tmp_path / "parts" / "chunk-00003.csv").unlink()
    (tmp_path / "summary.json").unlink()
    s = run(job, tmp_path, progress=False)
    assert s["chunks_processed"] == 1
    assert (tmp_path / "frames.csv").read_bytes() == serial_table
    # a chunk file truncated since it was written is done again (it had stopped the resume: 'does not hold every
    # frame exactly once; delete it and run again')
    f = tmp_path / "parts" / "chunk-00002.csv"
    f.write_bytes(f.read_bytes()[: len(f.read_bytes()) // 2])
    done = run(job, tmp_path, progress=False)
    assert done["chunks_processed"] == 1 and done["frames_per_s"] > 0
    assert (tmp_path / "frames.csv").read_bytes() == serial_table
    # a rerun that finds every chunk done keeps the timings of the run that processed them (it wrote 0 frames/s)
    again = run(job, tmp_path, progress=False)
    assert again["frames_per_s"] == done["frames_per_s"] and again["chunks_processed"] == 1 and "timings" in again
    assert json.loads((tmp_path / "summary.json").read_text())["frames_per_s"] == done["frames_per_s"]
    other = _job(flicker_sequence(PAPER_CAMERA, np.random.default_rng(6), "overlap", fps=100, duration_s=0.4), chunk=4)
    with pytest.raises(ValueError, match="other settings"):
        run(other, tmp_path, progress=False)


def _write_h5(path, frames, **attrs):
    with h5py.File(path, "w") as f:
        f["frames"] = frames
        f.attrs.update(attrs)


def test_simulated_frames_that_clip_are_noted(tmp_path):
    """simulate-sequence's note: the frames with pixels at full scale (65535) counted, none: no note."""
    from lf_flame.cli.sequence import clipped_frames_note
    frames = np.zeros((4, 6, 5), np.uint16)
    _write_h5(tmp_path / "dim.h5", frames)
    assert clipped_frames_note(tmp_path / "dim.h5") is None
    frames[1, :2, :2] = 65535
    frames[3, 0, 0] = 65535
    _write_h5(tmp_path / "clip.h5", frames)
    assert "2 of 4 frames clip the sensor (1-4 pixels at full scale)" in clipped_frames_note(tmp_path / "clip.h5")


def test_one_frame_of_a_recording_is_read_as_a_capture(tmp_path, capsys):
    """``RECORDING.h5:INDEX``: a recording's frame in its frames' units, with the camera it records, where a command
    reads a raw capture (with a calibration too, decoded then); an index past its frames refused, naming the range."""
    from lf_flame.cli import main
    from lf_flame.cli._io import _load_raw
    frames = (np.random.default_rng(2).random((3,) + PAPER_CAMERA.sensor_shape) * 65535).astype(np.uint16)
    _write_h5(tmp_path / "rec.h5", frames, camera=PAPER_CAMERA.to_json(), fps=100.0)
    raw, cam = _load_raw(f"{tmp_path / 'rec.h5'}:1")
    assert cam == PAPER_CAMERA and raw.dtype == np.float32
    np.testing.assert_allclose(raw, frames[1] / 65535.0, rtol=1e-6)
    assert main(["slopes", f"{tmp_path / 'rec.h5'}:3", "--out-prefix", str(tmp_path / "s")]) == 2
    assert "a recording of 3 frames takes a frame index 0 .. 2" in capsys.readouterr().err


def test_a_folder_of_frames_is_read_in_the_order_of_the_numbers_in_their_names(tmp_path):
    """Frames named frame_0 ... frame_11 without zero padding are read 0, 1, 2, ..., 10, 11 (text order read 0, 1,
    10, 11, 2, ...: a new user's 50 frames gave flicker frequencies of 4/12/16/18 Hz for 5/14/17/20 Hz); padded
    names and other files' order are as before."""
    from skimage import io
    for name in ("plain", "padded"):
        (tmp_path / name).mkdir()
        for i in range(12):
            io.imsave(tmp_path / name / (f"frame_{i}.png" if name == "plain" else f"frame_{i:03d}.png"),
                      np.full((4, 4), i, np.uint16), check_contrast=False)
        src, _ = open_source(tmp_path / name)
        assert [int(src.raw(i)[0, 0] * 65535 + 0.5) for i in range(12)] == list(range(12)), name


def test_recordings_on_file_and_in_a_folder_match_the_simulation(small_seq, serial_table, tmp_path):
    """The HDF5 stack of ``write_frames`` and the same frames as 16-bit PNG files give the
    same table; a frame with NaN or inf gets failed rows (the run goes on), a recording of nothing else stops."""
    from skimage import io
    h5 = write_frames(tmp_path / "rec.h5", SimulatedSource(small_seq, PAPER_CAMERA, 4), progress=False)
    src, attrs = open_source(h5)
    assert frame_rate(None, attrs) == small_seq.fps
    run(_job(small_seq, chunk=4, source=src), tmp_path / "h5", progress=False)
    folder = tmp_path / "pngs"
    folder.mkdir()
    with h5py.File(h5) as f:
        frames = f["frames"][:]
    for i, fr in enumerate(frames):
        io.imsave(folder / f"f{i:04d}.png", fr, check_contrast=False)
    src2, _ = open_source(folder)
    run(_job(small_seq, chunk=4, source=src2), tmp_path / "png", progress=False)
    assert (tmp_path / "png" / "frames.csv").read_bytes() == (tmp_path / "h5" / "frames.csv").read_bytes()
    import tifffile                                   # one multi-page TIFF (ImageJ's stack), as a high-speed camera's
    tifffile.imwrite(tmp_path / "stack.tif", frames, imagej=True, metadata={"finterval": 1 / small_seq.fps})
    src4, attrs4 = open_source(tmp_path / "stack.tif")
    assert frame_rate(None, attrs4) == pytest.approx(small_seq.fps)       # from ImageJ's frame interval
    assert src4.n_frames == len(frames)
    np.testing.assert_allclose(src4.raw(3), frames[3] / 65535, rtol=1e-6)
    run(_job(small_seq, chunk=4, source=src4), tmp_path / "tif", progress=False)
    assert (tmp_path / "tif" / "frames.csv").read_bytes() == (tmp_path / "h5" / "frames.csv").read_bytes()
    tifffile.imwrite(tmp_path / "4d.tif", frames[:2, None])
    with pytest.raises(ValueError, match=r"not a stack of frames \(T, H, W\)"):
        open_source(tmp_path / "4d.tif")
    (tmp_path / "cut.tif").write_bytes((tmp_path / "stack.tif").read_bytes()[:100])
    with pytest.raises(ValueError, match="is not a readable TIFF"):
        open_source(tmp_path / "cut.tif")
    # quantised to 16 bits: the heights stay within 0.05 mm of the float frames'
    a, b = pd.read_csv(tmp_path / "h5" / "frames.csv"), pd.read_csv(pd.io.common.BytesIO(serial_table))
    assert np.abs(a.height_mm - b.height_mm).max() < 0.05

    bad = frames.astype(np.float32) / 65535
    bad[5] = np.nan
    bad[6, 100:110, 200:205] = np.inf                    # a few corrupt pixels
    _write_h5(tmp_path / "nan.h5", bad, fps=100.0)
    src3, _ = open_source(tmp_path / "nan.h5")
    s = run(_job(small_seq, chunk=4, source=src3), tmp_path / "nan", progress=False)
    got = pd.read_csv(tmp_path / "nan" / "frames.csv")
    broken = got.frame.isin([5, 6])
    assert (got.failure[broken] == "frame holds NaN or inf").all() and got.height_mm[broken].isna().all()
    assert got.failure[~broken].isna().all() and got.height_mm[~broken].notna().all()   # the rest measured
    assert s["failed_frames"] == {k: 2 for k in range(len(small_seq.flames))}
    _write_h5(tmp_path / "all_nan.h5", np.full_like(bad, np.nan), fps=100.0)
    with pytest.raises(ValueError, match="every frame of the recording holds NaN or inf"):
        run(_job(small_seq, chunk=4, source=open_source(tmp_path / "all_nan.h5")[0]), tmp_path / "all_nan",
            progress=False)
    assert not (tmp_path / "all_nan" / "summary.json").exists()


def test_a_chunk_reads_its_hdf5_frames_in_one_open(small_seq, tmp_path, monkeypatch):
    """A chunk of 4 frames opens the file once for them (it opened it per frame) and reads the
    frames ``raw(i)`` reads; a job reads the recording's first frame once more, for the sensor's
    defective pixels (the same in every chunk)."""
    h5 = write_frames(tmp_path / "rec.h5", SimulatedSource(dataclasses.replace(small_seq, n_frames=8), PAPER_CAMERA,
                                                           1), progress=False)
    src, _ = open_source(h5)
    want = [src.raw(i) for i in range(4, 8)]
    opens = []
    real = h5py.File
    monkeypatch.setattr(h5py, "File", lambda *a, **k: opens.append(a[0]) or real(*a, **k))
    got = list(src.frames(4, 8))
    assert len(got) == 4 and all(np.array_equal(a, b) for a, b in zip(got, want))
    assert len(opens) == 1
    job = _job(small_seq, chunk=4, source=src)
    assert job.n_chunks == 2   # the length, read by the calling process, travels with the source
    opens.clear()
    res = process_chunk(1, job)
    assert sorted({r["frame"] for r in res["rows"]}) == [4, 5, 6, 7]
    assert len(opens) == 2 and "defects" in job._cache
    opens.clear()
    process_chunk(0, job)
    assert len(opens) == 1


def test_a_recording_whose_first_frame_is_dark_names_it_and_the_way_out(small_seq, tmp_path, capsys):
    """The planes of a recording without given ones are found in its first frame: a dark first frame is refused naming
    that frame and --depth, where 'views hold no light: there is nothing to find' named neither."""
    frames = np.stack(list(SimulatedSource(small_seq, PAPER_CAMERA, 1).frames(0, 3)))
    frames[0] = 0.0
    _write_h5(tmp_path / "dark0.h5", frames, fps=100.0)
    assert main(["sequence", str(tmp_path / "dark0.h5"), "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "first frame, where its planes are found" in err and "--depth" in err, err


def test_unmeasurable_frames_are_counted(small_seq, tmp_path):
    """Frames without light (here 2 of 8) cannot be measured on any plane: their count per
    plane is in the summary and peaks.csv (their values in the spectrum are the mean)."""
    frames = np.stack(list(SimulatedSource(small_seq, PAPER_CAMERA, 1).frames(0, 8)))
    frames[[2, 5]] = 0.0
    _write_h5(tmp_path / "dark.h5", frames, fps=100.0)
    src, _ = open_source(tmp_path / "dark.h5")
    s = run(_job(small_seq, chunk=4, source=src), tmp_path / "out", progress=False)
    assert s["failed_frames"] == {0: 2, 1: 2}
    assert pd.read_csv(tmp_path / "out" / "peaks.csv").n_failed.tolist() == [2, 2, 2, 2]   # 2 planes x 2 signals


def test_a_black_or_dimmed_frame_is_solved_from_scratch_not_continued(small_seq, tmp_path):
    """admm continues the previous frame's solve with two fills; a frame unlike it (black, or dimmed to 0.1) is
    solved from scratch: the black frame's planes are empty, as solved alone, and the dimmed frame's intensities
    are the lone solve's. Continued, the black frame had kept the previous frame's flames (heights 5-19 mm, no
    failure) and the dimmed frame six times its light on one plane."""
    frames = np.stack(list(SimulatedSource(small_seq, PAPER_CAMERA, 4).frames(0, 6)))
    frames[3] = 0.0
    frames[5] *= 0.1
    _write_h5(tmp_path / "odd.h5", frames, fps=100.0)
    src, _ = open_source(tmp_path / "odd.h5")
    rows = {}
    for chunk in (6, 1):                                       # continued within the chunk; every frame alone
        job = simulated_job(small_seq, PAPER_CAMERA, src, route="reconstruct-admm", chunk=chunk)[0]
        rows[chunk] = pd.concat([pd.DataFrame(process_chunk(c, job)["rows"]) for c in range(job.n_chunks)])
        rows[chunk] = rows[chunk].set_index(["frame", "plane"]).sort_index()
    cont, alone = rows[6], rows[1]
    assert cont.loc[3].failure.str.contains("empty").all(), cont.loc[3]
    dim = alone.loc[5].integrated_intensity.notna()
    assert dim.any()
    np.testing.assert_allclose(cont.loc[5].integrated_intensity[dim], alone.loc[5].integrated_intensity[dim],
                               rtol=1e-6)


def test_reconstruction_settings_reach_the_solver_and_the_run_identity(small_seq, tmp_path):
    """``iters``, ``tv``, ``saturation`` and ``operator_rays`` are the solver's: the job's
    planes are those of ``reconstruct`` with the same settings; each is in the identity
    (a resume after a change is refused), defaults resolved; the saturated pixels of each
    frame are counted in its rows."""
    from lf_flame.tomo.operator import EmissionOperator
    from lf_flame.tomo.solvers import DEFAULT_ITERS, DEFAULT_TV, reconstruct
    from lf_flame.tomo.defaults import ADMM_FILLS, ADMM_QUIET, ADMM_TV
    frames = np.stack(list(SimulatedSource(small_seq, PAPER_CAMERA, 1).frames(0, 2)))
    frames = np.clip(3.0 * frames, 0.0, 1.0)   # overexposed: clipped pixels
    _write_h5(tmp_path / "bright.h5", frames, fps=100.0)
    src, _ = open_source(tmp_path / "bright.h5")
    job = simulated_job(small_seq, PAPER_CAMERA, src, route="reconstruct-pd-tv", chunk=2, iters=2, tv=0.05,
                        saturation=0.9, operator_rays=1)[0]
    views = job.views(frames[0])
    with pytest.warns(UserWarning, match="at or above the saturation level 0.9"):       # 67 % clipped: said
        want = reconstruct(views, EmissionOperator(PAPER_CAMERA, list(job.depths_mm), rays_per_pixel=1), "pd-tv", 2,
                           tv=0.05, saturation=0.9)
    with pytest.warns(UserWarning, match="at or above the saturation level 0.9"):
        np.testing.assert_array_equal(job.planes(views), want.planes)
    assert want.settings["n_saturated"] > 0
    rows = pd.DataFrame(process_chunk(0, job)["rows"])       # (said once above, for this place in the job)
    left_out = [job.fit_data(*job.frame(f))[1] for f in frames]    # saturated, and 1 ray's spikes taken for defects
    assert all(np.array_equal(m, job.frame(f)[1] | (job.frame(f)[0] >= 0.9)) for m, f in zip(left_out, frames))
    assert rows.groupby("frame").n_saturated.first().tolist() == [int(m.sum()) for m in left_out]
    ident = job.identity()["reconstruction"]
    assert ident == dict(solver="pd-tv", iters=2, tv=0.05, saturation=0.9, operator_rays=1)
    for change in (dict(iters=3), dict(tv=0.1), dict(saturation=None), dict(operator_rays=2)):
        assert dataclasses.replace(job, **change).identity() != job.identity(), change
    default = dataclasses.replace(job, iters=None, tv=None).identity()["reconstruction"]
    assert (default["iters"], default["tv"]) == (DEFAULT_ITERS["pd-tv"], DEFAULT_TV)
    # admm's knobs not given follow the first frame's noise, once for the whole recording
    from lf_flame.tomo.noise_knobs import admm_knobs
    admm = dataclasses.replace(job, route="reconstruct-admm", iters=None, tv=None, operator_rays=None)
    r = admm.identity()["reconstruction"]
    v0 = admm.views(frames[0])
    knobs = admm_knobs(v0, v0 < 0.9)
    assert (r["iters"], r["tv"], r["lam"], r["l1"], r["start"], r["tol"]) == tuple(
        knobs[k] for k in ("fills", "tv", "lam", "l1", "start", "tol")) and r["admm_noise"] > 0
    assert (r["iters"], r["tv"]) in ((ADMM_QUIET["fills"], ADMM_QUIET["tv"]), (ADMM_FILLS, ADMM_TV))
    given = dataclasses.replace(admm, iters=3, tv=0.1).identity()["reconstruction"]
    assert (given["iters"], given["tv"]) == (3, 0.1) and "admm_noise" not in given
    assert simulated_job(small_seq, PAPER_CAMERA)[0].identity()["reconstruction"] is None


def test_bad_recordings_are_refused(tmp_path, small_seq):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no frames"):
        open_source(tmp_path / "empty")
    # one light field given as a recording (it had been 'not a readable HDF5 file: truncated or damaged'), and a
    # recording's frame index (sequence measures every frame)
    np.save(tmp_path / "one.npy", np.zeros((30, 30)))
    with pytest.raises(ValueError, match="one light field, not a recording"):
        open_source(tmp_path / "one.npy")
    _write_h5(tmp_path / "rec.h5", np.zeros((2, 30, 30)), fps=10.0)
    with pytest.raises(ValueError, match="give the file, not FILE:INDEX"):
        open_source(f"{tmp_path / 'rec.h5'}:1")
    job = _job(small_seq, chunk=4)
    for chunk in (0, -4, 2.5):
        with pytest.raises(ValueError, match=f"chunk .* must be a whole number >= 1. Received: {chunk}"):
            dataclasses.replace(job, chunk=chunk)
    with pytest.raises(ValueError, match="true frequency 70 Hz lies outside the spectrum of 100 frames/s"):
        dataclasses.replace(job, truth_freqs_hz=(7.0, 70.0))
    for bad in (dict(iters=-1), dict(tv=-0.1), dict(saturation=0.0), dict(operator_rays=0)):
        with pytest.raises(ValueError, match="Received"):
            dataclasses.replace(job, route="reconstruct-pd-tv", **bad)
    _write_h5(tmp_path / "one.h5", np.zeros((1, 2700, 1350), np.uint16), fps=100.0)
    src1, _ = open_source(tmp_path / "one.h5")
    with pytest.raises(ValueError, match="1 frame has no spectrum: give at least 2 frames"):
        run(_job(small_seq, source=src1), tmp_path / "one", progress=False)
    f = pd.DataFrame(dict(frame=range(8), plane=0, depth_mm=0.0, height_mm=np.sin(np.arange(8.0)),
                          integrated_intensity=1.0))
    with pytest.raises(ValueError, match="true frequency 90 Hz lies outside the spectrum"):
        peaks(spectra(f, 100.0), [90.0])
    with pytest.raises(ValueError, match="at least 2 frames"):
        peaks(spectra(f.iloc[:2], 100.0, nperseg=None).iloc[:1])
    with pytest.raises(ValueError, match="nperseg .* Received: 1"):
        spectra(f, 100.0, nperseg=1)
    _write_h5(tmp_path / "small.h5", np.zeros((3, 20, 30), np.uint16))
    src, _ = open_source(tmp_path / "small.h5")
    rows = pd.DataFrame(process_chunk(0, _job(small_seq, chunk=4, source=src))["rows"])   # each frame a failed row
    assert (rows.failure == "frame not processed: frame of 20 x 30 pixels; the camera's sensor is 2700 x 1350").all()
    with pytest.raises(ValueError, match=r"no frame of the recording could be processed \(frame 0: frame not "
                                         "processed: frame of 20 x 30 pixels"):
        run(_job(small_seq, chunk=4, source=src), tmp_path / "small", progress=False)
    with pytest.raises(ValueError, match="no frame rate"):
        frame_rate(None, {})
    with pytest.raises(ValueError, match="not strictly increasing"):
        frame_rate(None, {}, [0.0, 0.01, 0.01, 0.03])
    with pytest.raises(ValueError, match="not evenly spaced"):
        frame_rate(None, {}, [0.0, 0.01, 0.03])
    with pytest.raises(ValueError, match="disagrees"):
        frame_rate(250.0, {"fps": 500.0})
    with pytest.raises(ValueError, match="positive"):
        frame_rate(-5.0, {})


SMALL_CAMERA = PlenopticCamera(n_rows=40, n_cols=30, pixels_per_lenslet=9)


@pytest.fixture(scope="module")
def small_recording():
    """A recording of the paper's four flames on a 40 x 30-lenslet camera: 10 frames at 100 frames/s, 2 rays per
    pixel (360 x 270 pixels)."""
    seq = flicker_sequence(SMALL_CAMERA, np.random.default_rng(3), "paper", fps=100, duration_s=0.1)
    return seq, np.stack(list(SimulatedSource(seq, SMALL_CAMERA, 2).frames(0, seq.n_frames)))


def test_one_bad_frame_is_a_failed_row_and_the_recording_goes_on(small_recording, tmp_path, capsys):
    """A frame whose every pixel clipped (admm: 'every one of the views' 97200 samples is left out of the fit'; a
    uniform frame, it is now named as one, at full scale), a
    frame of another size in a folder of frames, and a black frame on lsqr (its planes NaN: 'plane contains 1200
    NaN or infinite values') had each aborted the whole recording (the folder left with job.json and an empty
    parts/). Each is now a failed row per plane naming why (the black frame's planes empty, unsolved, as admm's
    and shift-sum's are), the other frames measured; reconstruct refuses a light field without light before lsqr's
    NaN planes (it had printed pylops' RuntimeWarnings, then 'planes must be finite')."""
    seq, frames = small_recording
    clipped = frames.copy()
    clipped[4] = 1.0
    _write_h5(tmp_path / "clipped.h5", clipped, fps=100.0)
    black = frames.copy()
    black[6] = 0.0
    _write_h5(tmp_path / "black.h5", black, fps=100.0)
    (tmp_path / "folder").mkdir()
    for i, f in enumerate(frames):
        np.save(tmp_path / "folder" / f"frame_{i}.npy", f[:351] if i == 2 else f)
    cases = (("clipped.h5", "reconstruct-admm", 4, "frame not processed: its views carry no structure (each varies "
              "by 0 of its level across its lenslets, under 0.1; every pixel reads 1 (full scale: over-exposed))"),
             ("black.h5", "reconstruct-lsqr", 6, "plane is empty: no light"),               # as admm's and shift-sum's
             ("folder", "shift-sum", 2, "frame not processed: frame of 351 x 270 pixels; the camera's sensor is "
                                        "360 x 270"))
    for name, route, bad, why in cases:
        src, _ = open_source(tmp_path / name)
        job = simulated_job(seq, SMALL_CAMERA, src, route=route, chunk=5,
                            **(dict(iters=3) if route.endswith("lsqr") else {}))[0]
        s = run(job, tmp_path / f"out_{name}", progress=False)
        table = pd.read_csv(tmp_path / f"out_{name}" / "frames.csv", keep_default_na=False, na_values=[""])
        failed = table[table.failure.fillna("") != ""]
        assert set(failed.frame) == {bad} and failed.failure.str.startswith(why).all(), (name, failed.failure)
        assert list(s["unprocessed_frames"]) == ([str(bad)] if why.startswith("frame not") else []), name
        assert s["failed_frames"] == dict.fromkeys(range(4), 1)
        assert table[table.frame != bad].height_mm.notna().mean() > 0.9, name        # the others measured
    np.save(tmp_path / "zero.npy", np.zeros_like(frames[0]))
    (tmp_path / "small.toml").write_text("[camera]\npixels_per_lenslet = 9\nn_rows = 40\nn_cols = 30\n")
    capsys.readouterr()
    assert main(["reconstruct", str(tmp_path / "zero.npy"), "--camera", str(tmp_path / "small.toml"), "--depth", "0",
                 "--depth", "2", "--solver", "lsqr", "--out", str(tmp_path / "z.h5")]) == 2
    err = capsys.readouterr().err
    assert "zero.npy holds no light: its 97200 samples fitted are all 0" in err and "Warning" not in err, err


def test_a_folders_missing_or_unreadable_frame_is_a_failed_row_at_its_own_time(small_recording, tmp_path, capsys):
    """A folder of frames whose file numbers skip one (frame_3 gone) and with one file cut short (frame_6): each is a
    failed row at its own time and the frames after keep theirs (the missing file had moved every later frame one
    frame early, and a user's flicker read 20.20 Hz for 19.34; the truncated one had stopped the whole run)."""
    seq, frames = small_recording
    (tmp_path / "folder").mkdir()
    for i, f in enumerate(frames):
        if i != 3:
            np.save(tmp_path / "folder" / f"frame_{i:03d}.npy", f)
    path = tmp_path / "folder" / "frame_006.npy"
    path.write_bytes(path.read_bytes()[:5000])
    capsys.readouterr()
    src, _ = open_source(tmp_path / "folder")
    assert "skip 1 frame (frames 3," in capsys.readouterr().out and src.n_frames == len(frames)
    job = simulated_job(seq, SMALL_CAMERA, src, route="shift-sum", chunk=5)[0]
    run(job, tmp_path / "out", progress=False)
    table = pd.read_csv(tmp_path / "out" / "frames.csv", keep_default_na=False, na_values=[""])
    failed = table[table.failure.fillna("") != ""]
    assert set(failed.frame) == {3, 6} and failed.failure.str.startswith("frame not processed").all(), failed
    assert "missing from the folder" in failed[failed.frame == 3].failure.iloc[0]
    ok = table[table.frame == 7]
    assert ok.time_s.iloc[0] == pytest.approx(0.07) and ok.height_mm.notna().all()
    assert numbered_gaps(["a1.npy", "a3.npy", "a5.npy"]) == ("a1.npy", "a3.npy", "a5.npy")   # every other frame
    assert numbered_gaps(["x.npy", "y.npy", "z.npy"]) == ("x.npy", "y.npy", "z.npy")


def test_a_frame_written_only_in_part_is_a_failed_row(small_recording, tmp_path):
    """A frame whose lower half reads 0 (a dropped transfer) had been measured as any other, heights 2-3 mm short
    without a flag: where the frame before holds light in those rows it is a failed row naming why; a frame black
    throughout stays a frame (the flame out), and a frame whose bottom rows were dark before is no cut."""
    from lf_flame.recordings.chunk import truncated_rows
    seq, frames = small_recording
    cut = frames.copy()
    half = frames.shape[1] // 2
    cut[5, half:] = 0.0
    _write_h5(tmp_path / "cut.h5", cut, fps=100.0)
    src, _ = open_source(tmp_path / "cut.h5")
    job = simulated_job(seq, SMALL_CAMERA, src, route="shift-sum", chunk=10)[0]
    run(job, tmp_path / "out", progress=False)
    table = pd.read_csv(tmp_path / "out" / "frames.csv", keep_default_na=False, na_values=[""])
    failed = table[table.failure.fillna("") != ""]
    assert set(failed.frame) == {5} and failed.failure.str.contains("written only in part").all(), failed
    assert truncated_rows(cut[5], frames[4]) == frames.shape[1] - half
    assert truncated_rows(np.zeros_like(frames[0]), frames[4]) == 0 and truncated_rows(cut[5], None) == 0
    assert truncated_rows(cut[5], cut[5]) == 0                      # dark there before too: no cut


def test_a_uniform_glare_frame_is_a_failed_row_not_spectra_input(small_recording, tmp_path):
    """A frame set to one value throughout (a glare: 0.46 of full scale) had been measured as flames on three of four
    planes (heights about 5.2 mm flagged merged;cut;no-edge), its intensities in the spectra (plane 2's amplitude 11
    times the others'). Its views carry no structure (:func:`lf_flame.real.black_level.view_spread` 0, a flame's 1):
    it is a failed row on every plane naming why, and the spectra are those of the recording with that frame NaN."""
    seq, frames = small_recording
    out = {}
    for name, value in (("glare", 30000 / 65535), ("nan", np.nan)):
        bad = frames.copy()
        bad[3] = value
        _write_h5(tmp_path / f"{name}.h5", bad, fps=100.0)
        src, _ = open_source(tmp_path / f"{name}.h5")
        out[name] = run(simulated_job(seq, SMALL_CAMERA, src, chunk=5)[0], tmp_path / name, progress=False)
    table = pd.read_csv(tmp_path / "glare" / "frames.csv", keep_default_na=False, na_values=[""])
    failed = table[table.failure.notna()]
    assert set(failed.frame) == {3} and len(failed) == 4, failed
    assert failed.failure.str.startswith("frame not processed: its views carry no structure").all(), failed.failure
    assert list(out["glare"]["unprocessed_frames"]) == ["3"] and out["glare"]["failed_frames"] == dict.fromkeys(
        range(4), 1)
    glare, nan = (pd.read_csv(tmp_path / n / "spectra.csv") for n in ("glare", "nan"))
    pd.testing.assert_frame_equal(glare, nan)


def test_frame_times_and_rates_out_of_order_are_refused_by_name(tmp_path, capsys):
    """A NaN frame time is named as one (it had been 'not strictly increasing (at frame 1)', argmax of an all-False
    array); a times_s of 10 or 60 entries for 30 frames is refused naming both counts (it had been taken silently);
    an fps attribute that is no number names the attribute (it had been "could not convert string to float:
    'fast'"); a camera record that is not JSON names the file and the record (it had been json's bare message)."""
    from lf_flame.recordings.sources import source_frame_rate
    times = np.arange(30) / 100.0
    times[5] = np.nan
    with pytest.raises(ValueError, match=r"times_s\) hold NaN or inf \(first at frame 5\)"):
        frame_rate(None, {}, times)
    for n in (10, 60):
        path = tmp_path / f"t{n}.h5"
        _write_h5(path, np.zeros((30, 4, 4), np.uint16))
        with h5py.File(path, "a") as f:
            f["times_s"] = np.arange(n) / 100.0
        src, attrs = open_source(path)
        with pytest.raises(ValueError, match=f"hold {n} times .* for its 30 frames"):
            source_frame_rate(src, attrs)
    with pytest.raises(ValueError, match="fps attribute must be a number .* Received: 'fast'"):
        frame_rate(None, {"fps": "fast"})
    _write_h5(tmp_path / "cam.h5", np.zeros((3, 4, 4), np.uint16), fps=100.0, camera="{not json")
    np.savez(tmp_path / "cam.npz", raw=np.zeros((360, 270)), camera=np.array("{not json"))
    capsys.readouterr()
    for argv in (["sequence", str(tmp_path / "cam.h5"), "--quiet", "--out", str(tmp_path / "o")],
                 ["reconstruct", str(tmp_path / "cam.npz"), "--depth", "0", "--out", str(tmp_path / "r.h5")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err and "its 'camera' record is not readable JSON" in err, err
        assert Path(argv[1]).name in err, err


def test_cli_simulates_and_measures_a_recording(tmp_path, capsys):
    """The recording's four flames at 6, 9, 13 and 17 Hz (0.5 s at 100 frames/s, bins of
    2 Hz, the flames 3-4 Hz apart): each plane's measured peak is its own flame's."""
    rec = tmp_path / "rec.h5"
    freqs = [6.0, 9.0, 13.0, 17.0]
    assert main(["simulate-sequence", "--simulate", "paper", "--fps", "100", "--duration", "0.5",
                 *(a for f in freqs for a in ("--freq", str(f))), "--rays-per-pixel", "1", "--out", str(rec),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["sequence", str(rec), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    # the planes said, not taken quietly from the simulation's record
    assert "planes at the simulated recording's flames' depths (plane 0 the farthest): +20.00, +10.00, +0.00, " \
           "-10.00 mm" in capsys.readouterr().out
    # each plane's emission by default, as profiles and reconstruct give it (shift-and-sum on --route shift-sum)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["settings"]["route"] == "reconstruct-admm"
    pk = pd.read_csv(tmp_path / "out" / "peaks.csv").query("signal == 'height_mm'").sort_values("plane")
    assert np.all(np.abs(pk.dominant_hz.to_numpy() - freqs) <= pk.bin_hz.to_numpy()), pk
    assert (tmp_path / "out" / "sequence.png").stat().st_size > 10_000
    import tifffile                                   # the same frames as one ImageJ stack: its frame rate, no truth
    with h5py.File(rec) as f:
        tifffile.imwrite(tmp_path / "rec.tif", f["frames"][:], imagej=True, metadata={"finterval": 0.01})
    assert main(["sequence", str(tmp_path / "rec.tif"), *(a for d in (20, 10, 0, -10) for a in ("--depth", str(d))),
                 "--out", str(tmp_path / "tif"), "--quiet"]) == 0
    tif = pd.read_csv(tmp_path / "tif" / "peaks.csv").query("signal == 'height_mm'").sort_values("plane")
    np.testing.assert_array_equal(tif.dominant_hz.to_numpy(), pk.dominant_hz.to_numpy())
    capsys.readouterr()
    (tmp_path / "empty_dir").mkdir()
    assert main(["sequence", str(tmp_path / "empty_dir"), "--fps", "100", "--depth", "0",
                 "--out", str(tmp_path / "o2")]) == 2
    assert "holds no frames" in capsys.readouterr().err
    assert main(["sequence", str(tmp_path / "missing"), "--fps", "100", "--depth", "0",
                 "--out", str(tmp_path / "o2")]) == 2
    assert "recording not found" in capsys.readouterr().err
    assert main(["sequence", "--simulate", "paper", "--fps", "0", "--duration", "0.01", "--out", str(tmp_path / "o3")]) == 2
    assert "--fps must be positive and finite (frames/s). Received: 0" in capsys.readouterr().err
    for chunk in ("0", "-3"):
        assert main(["sequence", str(rec), "--chunk", chunk, "--out", str(tmp_path / "o4")]) == 2
        assert f"chunk (frames per task) must be a whole number >= 1. Received: {chunk}" in capsys.readouterr().err


def test_a_frame_over_exposed_against_the_rest_keeps_its_row_and_leaves_the_spectra():
    """One flash in a recording (56 % of its lit pixels clipped, the others none) measured 3 mm where the flame
    stands 20 mm tall: in the spectrum it would put the peak elsewhere; it takes the plane's mean there, its row
    stays. A recording whose every frame clips alike keeps them all, and a frame just over the warning beside
    frames clipping nearly as much is not singled out."""
    from lf_flame.recordings.runner import over_exposed_frames, recording_spectra
    t = np.arange(50) / 100.0
    height = 20.0 + 2.0 * np.sin(2 * np.pi * 6.0 * t)
    share = np.zeros(50)
    height[20], share[20] = 2.9, 0.56
    frames = pd.DataFrame(dict(frame=np.arange(50), plane=0, depth_mm=100.0, height_mm=height,
                               integrated_intensity=np.ones(50), clipped_share=share))
    spec, over = recording_spectra(frames, 100.0)
    assert over == [20] and frames.height_mm[20] == 2.9
    pk = peaks(spec).query("signal == 'height_mm'")
    assert pk.dominant_hz.iloc[0] == 6.0, pk
    assert peaks(spectra(frames, 100.0)).query("signal == 'height_mm'").dominant_hz.iloc[0] != 6.0   # the flash's
    assert over_exposed_frames(frames.assign(clipped_share=0.3)) == []
    assert over_exposed_frames(frames.assign(clipped_share=np.where(np.arange(50) == 7, 0.09, 0.06))) == []
    assert over_exposed_frames(frames.drop(columns="clipped_share")) == []


def test_cli_passes_the_reconstruction_settings(tmp_path, capsys):
    """``sequence --route reconstruct-*`` takes ``--iters --tv --saturation --operator-rays``:
    they are the run's settings, and its summary counts the saturated frames."""
    rec = tmp_path / "rec.h5"
    assert main(["simulate-sequence", "--simulate", "overlap", "--fps", "100", "--duration", "0.02",
                 "--rays-per-pixel", "1", "--out", str(rec), "--quiet"]) == 0
    assert main(["sequence", str(rec), "--route", "reconstruct-pd-tv", "--iters", "1", "--tv", "0.05",
                 "--saturation", "0.5", "--operator-rays", "1", "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["settings"]["reconstruction"] == dict(solver="pd-tv", iters=1, tv=0.05, saturation=0.5, operator_rays=1)
    assert s["n_saturated"]["frames"] == 2
    assert "2 of 2 frames clip the sensor, their clipped pixels left out of the fit" in capsys.readouterr().out
    assert main(["sequence", str(rec), "--route", "reconstruct-pd-tv", "--iters", "2", "--tv", "0.05",
                 "--saturation", "0.5", "--operator-rays", "1", "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "other settings" in capsys.readouterr().err


@pytest.mark.parametrize("layout", ["square", "hex"])
def test_a_recording_of_another_camera_is_decoded_and_reconstructed(tmp_path, layout, capsys):
    """A recording of the example camera (10.57 px lenslet images, rotated 0.4°; square or hexagonal grid) from
    the command line: its frames decoded with the white image's calibration, each plane solved by admm on the
    decoded views' operator (a hexagonal grid's on its own lattice): each plane's height spectrum peaks within one
    bin (1 Hz) of its flame's frequency, and its median height is the flame's within 5 % (square grid: 6.19 and
    3.36 mm against 6.15 and 3.37) or 9 % (hexagonal: 6.69 and 3.58 mm against 7.04 and 3.87)."""
    sheet = (Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
    cam = tmp_path / "cam.toml"
    cam.write_text(sheet.replace('layout = "square"', f'layout = "{layout}"'))
    assert main(["simulate", "--camera", str(cam), "--scene", "white", "--out", str(tmp_path / "white.npz")]) == 0
    assert main(["calibrate", str(tmp_path / "white.npz"), "--out", str(tmp_path / "cal.json")]) == 0
    assert main(["simulate-sequence", "--camera", str(cam), "--simulate", "overlap", "--fps", "100", "--duration",
                 "1", "--seed", "2", "--quiet", "--out", str(tmp_path / "frames.h5")]) == 0
    with h5py.File(tmp_path / "frames.h5") as f:
        flames = json.loads(f.attrs["sequence"])["flames"]
    capsys.readouterr()
    assert main(["sequence", str(tmp_path / "frames.h5"), "--camera", str(cam), "--calibration",
                 str(tmp_path / "cal.json"), "--white", str(tmp_path / "white.npz"), "--route", "reconstruct-admm",
                 *[x for fl in flames for x in ("--depth", str(fl["depth_offset_mm"]))], "--quiet",
                 "--out", str(tmp_path / "out")]) == 0
    pk = pd.read_csv(tmp_path / "out" / "peaks.csv").query("signal == 'height_mm'")
    assert len(pk) == len(flames) == 2
    for (_, row), fl in zip(pk.iterrows(), flames):
        assert abs(row.dominant_hz - fl["freq_hz"]) <= 1.0, (row, fl["freq_hz"])
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["n_frames"] == 100
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    heights = frames.groupby("plane").height_mm.median()
    for k, fl in enumerate(flames):
        assert abs(heights[k] / fl["height_mm"] - 1) < (0.05 if layout == "square" else 0.09), \
            (heights, [f["height_mm"] for f in flames])
    # each frame's samples left out of the fit, as reconstruct counts them on that frame (a hexagonal grid's axial
    # array's cells that hold no lenslet are no samples: they were counted, 3-4 times the samples left out)
    with h5py.File(tmp_path / "frames.h5") as f:
        np.save(tmp_path / "f0.npy", f["frames"][0] / 65535.0)
    capsys.readouterr()
    assert main(["reconstruct", str(tmp_path / "f0.npy"), "--camera", str(cam), "--calibration",
                 str(tmp_path / "cal.json"), *[x for fl in flames for x in ("--depth", str(fl["depth_offset_mm"]))],
                 "--no-figure", "--out", str(tmp_path / "f0.h5")]) == 0
    assert f"{frames.query('frame == 0').n_saturated.iloc[0]} of " in capsys.readouterr().out
    capsys.readouterr()
    assert main(["sequence", str(tmp_path / "frames.h5"), "--camera", str(cam), "--calibration",
                 str(tmp_path / "cal.json"), "--route", "reconstruct-admm", "--operator-rays", "4", "--depth", "5",
                 "--quiet", "--out", str(tmp_path / "traced")]) != 0
    assert "real frames are solved on their decoded views' exact operator" in capsys.readouterr().err


def test_a_simulated_recording_of_another_camera_is_decoded_at_its_flames_depths(tmp_path, capsys, monkeypatch):
    """``simulate-sequence --camera`` of the example camera (rotated grid), then ``sequence`` with the white image's
    calibration and no planes: each frame decoded and solved at the recording's own flames' depths, the grid
    checked in the first frame only and the white image sampled once (frames that record none, as files of a folder: at the depths found in the
    first frame, within 1 mm); without the calibration, refused naming it (a raw frame of that grid is no grid of
    whole lenslet images)."""
    import lf_flame.real.decoding as decoding
    checked, whites = [], []
    check_grid, white_samples = decoding.check_grid, decoding.white_samples
    monkeypatch.setattr(decoding, "check_grid", lambda *a, **k: checked.append(1) or check_grid(*a, **k))
    monkeypatch.setattr(decoding, "white_samples", lambda *a, **k: whites.append(1) or white_samples(*a, **k))
    sheet = (Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
    cam = tmp_path / "cam.toml"
    cam.write_text(sheet)
    for argv in (["simulate", "--camera", str(cam), "--scene", "white", "--rays-per-pixel", "8", "--out",
                  str(tmp_path / "white.npz")], ["calibrate", str(tmp_path / "white.npz"), "--out", str(tmp_path / "cal.json")],
                 ["simulate-sequence", "--camera", str(cam), "--simulate", "overlap", "--fps", "100", "--duration", "0.04",
                  "--rays-per-pixel", "16", "--quiet", "--out", str(tmp_path / "frames.h5")]):
        assert main(argv) == 0
    with h5py.File(tmp_path / "frames.h5") as f:
        flames = json.loads(f.attrs["sequence"])["flames"]
    capsys.readouterr()
    assert main(["sequence", str(tmp_path / "frames.h5"), "--camera", str(cam), "--quiet", "--out",
                 str(tmp_path / "bare")]) == 2
    assert "give its white image's --calibration" in capsys.readouterr().err
    assert main(["sequence", str(tmp_path / "frames.h5"), "--camera", str(cam), "--calibration",
                 str(tmp_path / "cal.json"), "--route", "reconstruct-admm", "--quiet", "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["n_frames"] == 4 and len(checked) == 1
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert sorted(frames.depth_mm.unique()) == pytest.approx(sorted(fl["depth_offset_mm"] for fl in flames), abs=1e-4)
    # the recording's truth beside: each plane's flame's frequency and heights
    pk = pd.read_csv(tmp_path / "out" / "peaks.csv").query("signal == 'height_mm'")
    assert list(pk.true_hz) == pytest.approx([fl["freq_hz"] for fl in flames])
    assert (frames.height_mm - frames.height_mm_true).abs().median() < 0.1 * frames.height_mm_true.median()
    # the same frames as files of a folder, which record no flames: the depths found in the first frame
    (tmp_path / "folder").mkdir()
    with h5py.File(tmp_path / "frames.h5") as f:
        for i, frame in enumerate(f["frames"][:]):
            np.save(tmp_path / "folder" / f"f{i:03d}.npy", frame)
    capsys.readouterr()
    assert main(["sequence", str(tmp_path / "folder"), "--camera", str(cam), "--calibration", str(tmp_path / "cal.json"),
                 "--fps", "100", "--route", "reconstruct-admm", "--quiet", "--out", str(tmp_path / "found")]) == 0
    printed = capsys.readouterr()
    assert "planes, as reconstruct finds a capture's, in its first frame" in printed.out
    assert "black level" not in printed.err
    found = sorted(pd.read_csv(tmp_path / "found" / "frames.csv").depth_mm.unique())
    assert found == pytest.approx(sorted(fl["depth_offset_mm"] for fl in flames), abs=1.0), found
    # the same frames without their camera file: the paper's camera was taken, and the refusal says so
    assert main(["sequence", str(tmp_path / "folder"), "--calibration", str(tmp_path / "cal.json"), "--fps", "100",
                 "--quiet", "--out", str(tmp_path / "nocam")]) == 2
    assert "no camera file given, and the recording stores none" in capsys.readouterr().err
    # the frames with an offset of 3 % of their peak left in (no dark frame), decoded with the white image: the
    # first frame's unlit pixels say so
    (tmp_path / "offset").mkdir()
    for i, p in enumerate(sorted((tmp_path / "folder").glob("*.npy"))):
        frame = np.load(p)
        np.save(tmp_path / "offset" / p.name, frame + 0.03 * frame.max())
    whites.clear()
    assert main(["sequence", str(tmp_path / "offset"), "--camera", str(cam), "--calibration", str(tmp_path / "cal.json"),
                 "--white", str(tmp_path / "white.npz"), "--fps", "100", "--route", "shift-sum", "--depth",
                 str(found[0]), "--quiet", "--out", str(tmp_path / "offset_out")]) == 0
    assert "black level" in capsys.readouterr().err
    assert len(whites) == 1                                 # its white image sampled once for the four frames
    # the white image read in the frames' units, and by default the calibration's (as decode reads it): a 16-bit
    # TIFF of it gives the float file's measurements (its counts were taken for a white 65535 times as bright), and
    # so does none given (the frames were left undivided)
    import tifffile
    with np.load(tmp_path / "white.npz") as z:
        tifffile.imwrite(tmp_path / "white.tif", np.round(np.clip(z["raw"], 0, 1) * 65535).astype(np.uint16))
    tables = {}
    for white in ("white.npz", "white.tif", None):
        assert main(["sequence", str(tmp_path / "folder"), "--camera", str(cam), "--calibration",
                     str(tmp_path / "cal.json"), *(["--white", str(tmp_path / white)] if white else []), "--fps", "100",
                     "--route", "shift-sum", "--depth", str(found[0]), "--quiet", "--out", str(tmp_path / f"w_{white}")]) == 0
        tables[white] = pd.read_csv(tmp_path / f"w_{white}" / "frames.csv")
    for white in ("white.tif", None):
        np.testing.assert_allclose(tables[white].integrated_intensity, tables["white.npz"].integrated_intensity,
                                   rtol=2e-3)
        np.testing.assert_allclose(tables[white].height_mm, tables["white.npz"].height_mm, atol=0.05)


def test_a_colour_recording_is_levelled_as_reconstruct_levels_a_capture(tmp_path, capsys, colour_capture, monkeypatch):
    """A colour camera's recording (the example camera with an RGGB CFA): each frame is decoded with its channels
    apart and levelled into one light field exactly as ``reconstruct`` levels the same capture (the same views and
    the same samples left out: blue), its white image sampled once for every frame, solved on the operator of
    nearest pixels; ``sequence`` runs it from the command line."""
    import lf_flame.real.decoding as decoding
    whites, white_samples = [], decoding.white_samples
    monkeypatch.setattr(decoding, "white_samples", lambda *a, **k: whites.append(1) or white_samples(*a, **k))
    from lf_flame.cli._io import light_field
    from lf_flame.real.calibration import GridCalibration
    from lf_flame.recordings.job import SequenceJob
    from lf_flame.real.readers import read_light_field
    from lf_flame.temperature.mosaic import monochrome_light_field
    cam, d = colour_capture(3, 4, white_rays=4), str(tmp_path)
    whites.clear()                  # calibrate samples the white image for its note of dark lenslets: not a frame's

    def run(*argv):
        assert main([str(x) for x in argv]) == 0, capsys.readouterr().err
    lf = monochrome_light_field(read_light_field(f"{d}/scene.h5", str(cam)))
    assert lf.channels is None and "levelled" in lf.meta["monochrome"]
    assert np.array_equal(light_field(argparse.Namespace(raw=f"{d}/scene.h5", camera=str(cam))).views, lf.views)
    cal = GridCalibration.load(f"{d}/cal.json")
    depth = float(json.loads(str(np.load(f"{d}/scene.npz")["objects"]))[0]["depth_offset_mm"])
    job = SequenceJob(None, lf.camera, 100.0, (depth,), (lf.camera.slope_for_depth(depth),), (None,),
                      "reconstruct-admm", cal.to_dict(), f"{d}/white.npz",
                      sensor=dict(name="Nikon 5100 (NPL)", pattern="RGGB", phase=[0, 0]))
    views, leave = job.frame(np.load(f"{d}/scene.npz")["raw"])
    assert np.array_equal(views, lf.views) and np.array_equal(leave, lf.leave_out)
    dark, dark_leave = job.frame(np.zeros(cal.sensor_shape))         # a dark frame (the flame out): zeros, no error
    assert not np.any(dark) and np.array_equal(dark_leave, leave)
    assert len(whites) == 1
    assert job.operator().interpolation is None                       # nearest pixels: no interpolation
    from lf_flame.tomo.defaults import OFFSET_KNOBS
    from lf_flame.tomo.exact import offset_bins_for
    bins = offset_bins_for(lf.camera, (depth,))                       # each sample at its own pixel where it matters
    assert job.operator().offset_bins == (None if bins == 1 else bins)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        np.save(frames / f"f{i}.npy", np.load(f"{d}/scene.npz")["raw"])
    capsys.readouterr()
    run("sequence", frames, "--camera", cam, "--calibration", f"{d}/cal.json", "--fps", 100, "--route",
        "reconstruct-admm", "--depth", depth, "--quiet", "--out", f"{d}/out")
    assert "levelled into one light field" in capsys.readouterr().out
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["n_frames"] == 2
    r = json.loads((tmp_path / "out" / "job.json").read_text())["reconstruction"]
    if bins > 1:                                                     # the sub-views' fills, as reconstruct's
        assert (r["iters"], r["tol"]) == (OFFSET_KNOBS["fills"], OFFSET_KNOBS["tol"])


def test_a_recordings_found_planes_near_each_other_keep_their_own_flames(tmp_path, capsys):
    """A recording without given planes: those found in its first frame, where two flames stand side by side
    1.6 mm apart in depth (2.7 lenslets of parallax across the aperture), are held to their own regions where they
    meet, as 'reconstruct' holds them, in every frame: each plane measures its own flame, not half of each (the
    run's identity records the regions' digest)."""
    from lf_flame.simulate.scenes_time import FlameSequence, FlickerFlame
    flames = (FlickerFlame(-0.8, 12.0, -3.0, -8.0, 0.6, 7.0), FlickerFlame(0.8, 12.0, 3.0, -8.0, 0.6, 11.0))
    frames = np.stack(list(SimulatedSource(FlameSequence("near", flames, 100.0, 3, 5), PAPER_CAMERA, 4).frames(0, 3)))
    _write_h5(tmp_path / "near.h5", frames, fps=100.0)          # no truth stored: the planes are found
    out = tmp_path / "out"
    assert main(["sequence", str(tmp_path / "near.h5"), "--route", "reconstruct-admm", "--quiet", "--out",
                 str(out)]) == 0
    assert "support_sha256" in json.loads((out / "summary.json").read_text())["settings"]
    assert sorted(pd.read_csv(out / "frames.csv").depth_mm.unique()) == pytest.approx([-0.8, 0.8], abs=0.2)
    # the job's planes of a frame so held: each holds its own flame (left: x < 0, right: x > 0)
    from lf_flame.cli.sequence import first_frame_depths
    from lf_flame.recordings.job import SequenceJob
    from lf_flame.tomo.found_planes import found_support
    src, _ = open_source(tmp_path / "near.h5")
    depths, found = first_frame_depths(src, PAPER_CAMERA)
    job = SequenceJob(src, PAPER_CAMERA, 100.0, tuple(depths), tuple(map(PAPER_CAMERA.slope_for_depth, depths)),
                      (None, None), "reconstruct-admm", support=found_support(found, PAPER_CAMERA))
    planes = job.planes(job.views(frames[1]))
    half = planes.shape[2] // 2
    left, right = planes[:, :, :half].sum(axis=(1, 2)), planes[:, :, half:].sum(axis=(1, 2))
    assert right[0] < 0.01 * left[0] and left[1] < 0.01 * right[1], (left, right)    # without: 4 %
    for bad in (dict(support=np.ones((2, 3, 3), bool)), dict(route="shift-sum")):     # another grid; no admm
        with pytest.raises(ValueError, match="support holds admm's planes"):
            dataclasses.replace(job, **bad)


def test_a_frame_of_a_simulated_recording_takes_depths_scene(tmp_path, capsys):
    """``reconstruct REC.h5:INDEX --depths scene``: the planes of the recording's flames (simulate-sequence stores
    them); it was refused as storing no objects with depths."""
    rec = tmp_path / "rec.h5"
    assert main(["simulate-sequence", "--simulate", "overlap", "--fps", "100", "--duration", "0.02",
                 "--rays-per-pixel", "1", "--out", str(rec), "--quiet"]) == 0
    with h5py.File(rec) as f:
        flames = json.loads(f.attrs["sequence"])["flames"]
    capsys.readouterr()
    assert main(["reconstruct", f"{rec}:1", "--depths", "scene", "--no-figure", "--out", str(tmp_path / "r.h5")]) == 0
    with h5py.File(tmp_path / "r.h5") as f:
        got = sorted(f["depths_mm"][()])
    np.testing.assert_allclose(got, sorted(dict.fromkeys(fl["depth_offset_mm"] for fl in flames)), atol=1e-9)


def test_a_recording_in_counts_with_defective_pixels_gives_its_planes_in_counts(small_recording, tmp_path):
    """A recording's frames in a 12-bit sensor's counts (floats up to 4095: integer files are read scaled to [0, 1])
    whose fit is a mask (the sensor's defective pixels, found in the first frame) are solved in units of their
    clipping level, as its [0, 1] frames are: the same heights, the integrated intensities times 4095 (the mask had
    dropped the level, and TV was applied in counts)."""
    seq, frames = small_recording
    rng = np.random.default_rng(5)
    noisy = np.clip(frames + rng.normal(0.0, 0.03, frames.shape), 0.0, 1.0)
    hot = rng.choice(frames[0].size, 20, replace=False)
    for f in noisy:
        f.flat[hot] = 1.0                                                # the sensor's hot pixels, every frame
    counts = np.round(noisy * 4095)
    _write_h5(tmp_path / "unit.h5", (counts / 4095).astype(np.float32), fps=100.0)
    _write_h5(tmp_path / "counts.h5", counts.astype(np.float32), fps=100.0)
    tables = {}
    for name in ("unit", "counts"):
        src, _ = open_source(tmp_path / f"{name}.h5")
        job = simulated_job(seq, SMALL_CAMERA, src, route="reconstruct-admm", chunk=5)[0]
        run(job, tmp_path / f"out_{name}", progress=False)
        tables[name] = pd.read_csv(tmp_path / f"out_{name}" / "frames.csv")
    a, b = tables["unit"], tables["counts"]
    assert a.failure.isna().mean() > 0.9 and (a.n_saturated > 0).all()              # the hot pixels left out
    np.testing.assert_allclose(b.integrated_intensity / 4095, a.integrated_intensity, rtol=1e-3)
    np.testing.assert_allclose(b.height_mm, a.height_mm, atol=1e-3)


def test_a_monochrome_recording_decoded_with_its_white_image_is_solved_in_the_white_images_units():
    """Each frame's unit for the solvers (``SequenceJob.unit``): a monochrome camera's frames decoded with a white
    image are its radiance ratio (unit 1, as ``LightField.unit``), whatever their clipping level (12-bit counts read
    scaled to [0, 1] clip at 0.0625: the weights had been 16 times too strong); a colour camera's decoded views and
    undecoded frames keep their level."""
    from lf_flame.recordings.job import SequenceJob
    counts = np.random.default_rng(0).integers(0, 4096, (40, 40))          # 12-bit counts, a quarter clipped
    counts[:, :10] = 4095
    frame = (counts / 65535).astype(np.float32)                               # read scaled to [0, 1]: top 0.0625
    args = (None, PAPER_CAMERA, 100.0, (0.0,), (0.0,), (None,), "reconstruct-admm")
    assert SequenceJob(*args, {"pitch_px": 15.0}, "white.npz").unit(frame) == 1.0
    assert SequenceJob(*args, {"pitch_px": 15.0}, "white.npz", sensor=dict(name="Nikon 5100 (NPL)", pattern="RGGB",
                                                                              phase=[0, 0])).unit(frame) == frame.max()
    assert SequenceJob(*args).unit(frame) == frame.max()                     # 4095 / 65535
    assert SequenceJob(*args, {"pitch_px": 15.0}, None).unit(frame) == frame.max()    # no white image: counts
