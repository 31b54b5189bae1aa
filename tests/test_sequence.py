"""Flame recordings (issue 26): per-plane flicker frequencies, the Dask path against the
serial one, a real multi-process cluster with a worker killed mid-run, resuming, and the
bad inputs a user meets."""
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

from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.cli import main
from lf_flame.simulate.scenes_time import flicker_sequence
from lf_flame.recordings.sources import SimulatedSource, frame_rate, open_source, write_frames
from lf_flame.recordings.job import process_chunk, simulated_job
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


def test_frequencies_are_distinct_and_clear_of_harmonics():
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "paper")
    f = [fl.freq_hz for fl in seq.flames]
    assert all(5 <= v <= 20 for v in f)
    assert all(abs(a - b) >= 2 and abs(2 * a - b) >= 2 for i, a in enumerate(f) for j, b in enumerate(f) if i != j)
    with pytest.raises(ValueError, match="second harmonic"):
        flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "paper", fps=30)
    with pytest.raises(ValueError, match="frequencies"):
        flicker_sequence(PAPER_CAMERA, np.random.default_rng(3), "overlap", freqs_hz=[8.0])


@pytest.fixture(scope="module")
def small_seq():
    """A short recording: 40 frames, chunks of 4."""
    return flicker_sequence(PAPER_CAMERA, np.random.default_rng(5), "overlap", fps=100, duration_s=0.4)


@pytest.fixture(scope="module")
def serial_table(small_seq, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    run(_job(small_seq, chunk=4), out, progress=False)
    return (out / "frames.csv").read_bytes()


def test_the_dask_path_writes_the_serial_tables(small_seq, serial_table, tmp_path):
    s = run(_job(small_seq, chunk=4), tmp_path, workers=2, progress=False)
    assert s["workers"] == 2
    assert (tmp_path / "frames.csv").read_bytes() == serial_table


def _dask_cli():
    exe = Path(sys.executable).with_name("dask")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]


def test_a_killed_worker_loses_and_duplicates_no_frame(small_seq, serial_table, tmp_path):
    """A real cluster over TCP (``dask scheduler`` and two ``dask worker`` processes, no
    nanny): one worker is killed with SIGKILL while chunks are still to do; the run
    completes, every frame once, the same table as the serial path."""
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
        with Client(scheduler_file=str(sf), timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
        job = _job(small_seq, chunk=4)   # 10 chunks of 4 frames
        out = tmp_path / "run"
        result = {}
        th = threading.Thread(target=lambda: result.update(s=run(job, out, scheduler=str(sf), progress=False)))
        th.start()
        for _ in range(1200):
            if len(list((out / "parts").glob("chunk-*.csv"))) >= 2:
                break
            time.sleep(0.05)
        done_at_kill = len(list((out / "parts").glob("chunk-*.csv")))
        procs[1].send_signal(signal.SIGKILL)
        th.join(timeout=300)
        assert not th.is_alive()
        assert done_at_kill < job.n_chunks, "the run ended before the worker was killed"
        assert procs[1].wait(timeout=10) == -signal.SIGKILL
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
    other = _job(flicker_sequence(PAPER_CAMERA, np.random.default_rng(6), "overlap", fps=100, duration_s=0.4), chunk=4)
    with pytest.raises(ValueError, match="other settings"):
        run(other, tmp_path, progress=False)


def _write_h5(path, frames, **attrs):
    with h5py.File(path, "w") as f:
        f["frames"] = frames
        f.attrs.update(attrs)


def test_recordings_on_file_and_in_a_folder_match_the_simulation(small_seq, serial_table, tmp_path):
    """The HDF5 stack of ``write_frames`` and the same frames as 16-bit PNG files give the
    same table; a frame of NaN stops the run with its index and leaves no summary."""
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
    # quantised to 16 bits: the heights stay within 0.05 mm of the float frames'
    a, b = pd.read_csv(tmp_path / "h5" / "frames.csv"), pd.read_csv(pd.io.common.BytesIO(serial_table))
    assert np.abs(a.height_mm - b.height_mm).max() < 0.05

    bad = frames.astype(np.float32) / 65535
    bad[5] = np.nan
    _write_h5(tmp_path / "nan.h5", bad, fps=100.0)
    src3, _ = open_source(tmp_path / "nan.h5")
    with pytest.raises(ValueError, match="frame 5: frame holds NaN"):
        run(_job(small_seq, chunk=4, source=src3), tmp_path / "nan", progress=False)
    assert not (tmp_path / "nan" / "summary.json").exists()


def test_bad_recordings_are_refused(tmp_path, small_seq):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no frames"):
        open_source(tmp_path / "empty")
    _write_h5(tmp_path / "small.h5", np.zeros((3, 20, 30), np.uint16))
    src, _ = open_source(tmp_path / "small.h5")
    with pytest.raises(ValueError, match="frame 0: frame of 20 x 30 pixels; the camera's sensor is 2700 x 1350"):
        process_chunk(0, _job(small_seq, chunk=4, source=src))
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


def test_cli_simulates_and_measures_a_recording(tmp_path, capsys):
    rec = tmp_path / "rec.h5"
    assert main(["simulate-sequence", "--simulate", "overlap", "--fps", "100", "--duration", "0.2", "--freq", "8",
                 "--freq", "13", "--out", str(rec), "--quiet"]) == 0
    assert main(["sequence", str(rec), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    pk = pd.read_csv(tmp_path / "out" / "peaks.csv")
    assert list(pk.true_hz.unique()) == [8.0, 13.0]
    assert (tmp_path / "out" / "sequence.png").stat().st_size > 10_000
    assert main(["sequence", str(tmp_path / "empty_dir"), "--fps", "100", "--depth", "0",
                 "--out", str(tmp_path / "o2")]) == 2
    assert "recording not found" in capsys.readouterr().err
