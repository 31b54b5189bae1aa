"""What a new user meets first on the command line: bad input files, outputs that cannot be
written, Ctrl-C, options out of range, leftovers of a failed run. One exit status for bad input
(2), one for a failure while running (1), 130 for Ctrl-C; each with one line naming the problem."""
import json
import os
import stat
import types

import h5py
import numpy as np
import pytest

import lf_flame.cli as cli
from lf_flame.cli import main
from lf_flame.cli.options import check_output


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture()
def damaged(tmp_path):
    """Empty and truncated .npz, .npy and .h5 files."""
    good = tmp_path / "good.npz"
    np.savez(good, raw=np.random.default_rng(0).random((60, 60)))
    np.save(tmp_path / "good.npy", np.ones((60, 60)))
    with h5py.File(tmp_path / "good.h5", "w") as f:
        f["views"] = np.ones((3, 3, 20, 20), np.float32)
    files = {}
    for name in ("good.npz", "good.npy", "good.h5"):
        data = (tmp_path / name).read_bytes()
        ext = name.split(".")[1]
        (tmp_path / f"empty.{ext}").write_bytes(b"")
        (tmp_path / f"cut.{ext}").write_bytes(data[: len(data) // 2])
        files[ext] = (tmp_path / f"empty.{ext}", tmp_path / f"cut.{ext}")
    return files


def test_damaged_inputs_are_refused_in_one_line_naming_the_file(damaged, tmp_path, capsys):
    """Empty or truncated .npz/.npy (NumPy's EOFError, zipfile's BadZipFile, a reshape) and .h5
    files (HDF5's OSError) given to refocus, reconstruct and sequence: exit 2, one line naming
    the file and what is wrong with it, no traceback, nothing written."""
    out = tmp_path / "out"
    cases = [(["refocus", str(p), "--slope", "0", "--out", str(out / "r.npz")], p)
             for p in (*damaged["npz"], *damaged["npy"])]
    cases += [(["reconstruct", str(p), "--depth", "0", "--out", str(out / "r.h5")], p) for p in damaged["h5"]]
    cases += [(["sequence", str(p), "--depth", "0", "--fps", "100", "--out", str(out / "seq")], p)
              for p in damaged["h5"]]
    for argv, path in cases:
        assert main(argv) == 2, argv
        line = _one_error_line(capsys.readouterr().err)
        assert line.startswith("error: ") and str(path) in line, line
        assert ("empty" if path.stat().st_size == 0 else "truncated") in line, line
    assert not out.exists()


def test_a_missing_input_gives_2_before_any_work(tmp_path, capsys, monkeypatch):
    """refocus, reconstruct, profiles, sequence and temperature: a missing input file is bad
    input (exit 2, one line naming it), refused before any computation starts."""
    import lf_flame.tomo.solvers as solvers

    def no_work(*a, **k):
        raise AssertionError("the work started")
    monkeypatch.setattr(solvers, "reconstruct", no_work)
    gone = tmp_path / "gone.npz"
    out = tmp_path / "out"
    for argv in (["refocus", str(gone), "--slope", "0", "--out", str(out / "r.npz")],
                 ["reconstruct", str(gone), "--out", str(out / "r.h5")],
                 ["reconstruct", str(tmp_path / "gone.h5"), "--out", str(out / "r.h5")],
                 ["profiles", str(gone), "--out", str(out / "p")],
                 ["sequence", str(tmp_path / "gone.h5"), "--depth", "0", "--out", str(out / "s")],
                 ["temperature", str(gone), "--calibration", str(tmp_path / "bb.json"), "--out", str(out / "t.h5")]):
        assert main(argv) == 2, argv
        line = _one_error_line(capsys.readouterr().err)
        assert "gone." in line and "not found" in line, line
    assert not out.exists()


def test_an_output_that_cannot_be_written_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """An output under a regular file, or in a folder that is not writable, is refused (exit 2,
    one line naming the path) before the command runs; the check itself refuses an unwritable
    folder (chmod: not as root, who may write anywhere)."""
    ran = []
    monkeypatch.setattr(cli.temperature, "cmd_temperature", lambda a: ran.append(a))
    monkeypatch.setattr(cli.volume, "cmd_reconstruct", lambda a: ran.append(a))
    afile = tmp_path / "afile.txt"
    afile.write_text("x")
    for argv in (["temperature", "in.npz", "--calibration", "bb.json", "--out", str(afile / "t.h5")],
                 ["reconstruct", "in.npz", "--out", str(afile / "deeper" / "r.h5")]):
        assert main(argv) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert f"cannot write {afile}" in line and f"{afile} is a file, not a folder" in line, line
    monkeypatch.setattr(os, "access", lambda path, mode: False)      # as an unwritable folder looks
    assert main(["reconstruct", "in.npz", "--out", str(tmp_path / "new" / "r.h5")]) == 2
    assert f"the folder {tmp_path} is not writable" in capsys.readouterr().err
    monkeypatch.undo()
    assert ran == []
    check_output(tmp_path / "new" / "deeper" / "r.h5")                 # creatable: accepted
    check_output(tmp_path)                                             # an existing folder (sequence --out)
    if os.geteuid() == 0:
        pytest.skip("root may write into any folder: the chmod case needs another user")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with pytest.raises(ValueError, match="is not writable"):
            check_output(locked / "r.h5")
    finally:
        locked.chmod(stat.S_IRWXU)


def test_an_option_no_file_could_be_named_is_not_taken_for_one():
    """The inputs named by a command's options are the values that are files; a value no path can be (50 depths in
    one --depths list, past the 255 characters a file name may hold) is none (it had stopped the command with 'File
    name too long')."""
    from lf_flame.cli.options import _input_paths
    depths = ",".join(f"{-23 + i:.3f}" for i in range(50))
    assert len(depths) > 255 and _input_paths(types.SimpleNamespace(depths=depths, out="x.h5")) == []


def test_an_output_that_would_overwrite_an_input_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """--out naming the command's input (a capture, a recording, a white image, a blackbody image), or an HDF5
    output named .png whose figure would be written over it, is refused before the work: each had replaced the
    input (or the temperatures, with the figure). A prefix (profiles) and refocus's PNG are outputs as asked."""
    ran = []
    for mod, name in ((cli.temperature, "cmd_temperature"), (cli.real, "cmd_decode"), (cli.real, "cmd_calibrate"),
                      (cli.temperature_calibration, "cmd_calibrate_temperature"), (cli.profiles, "cmd_profiles"),
                      (cli.optics, "cmd_refocus"), (cli.volume, "cmd_reconstruct")):
        monkeypatch.setattr(mod, name, lambda a: ran.append(a))
    for f in ("cap.h5", "raw.tif", "white.npz", "bb1.h5", "bb2.h5", "cap.png"):
        (tmp_path / f).write_bytes(b"x")
    t = lambda f: str(tmp_path / f)                                               # noqa: E731
    for argv, culprit in ((["temperature", t("cap.h5"), "--calibration", "bb.json", "--out", t("cap.h5")], "cap.h5"),
                          (["temperature", t("cap.h5") + ":3", "--calibration", "bb.json", "--out", t("cap.h5")],
                           "cap.h5"),
                          (["decode", t("raw.tif"), "--calibration", "c.json", "--out", t("raw.tif")], "raw.tif"),
                          (["calibrate", t("white.npz"), "--out", t("white.npz")], "white.npz"),
                          (["calibrate-temperature", t("bb1.h5"), t("bb2.h5"), "--temperature", "1600",
                            "--temperature", "2400", "--out", t("bb2.h5")], "bb2.h5"),
                          (["reconstruct", t("cap.png"), "--out", t("cap.h5")], "cap.png")):  # its figure: cap.png
        assert main(argv) == 2, argv
        assert f"would overwrite the input {tmp_path / culprit}" in _one_error_line(capsys.readouterr().err)
    assert main(["temperature", t("cap.h5"), "--calibration", "bb.json", "--out", t("y.png")]) == 2
    assert "name the HDF5 file" in capsys.readouterr().err
    (tmp_path / "adir").mkdir()                     # a file output that is a folder: refused before the work (it had
    assert main(["reconstruct", t("cap.h5"), "--out", t("adir")]) == 2          # failed after it, on 'adir.part')
    assert "is a folder: name the file" in capsys.readouterr().err
    (tmp_path / "fig.png").mkdir()                  # its figure's place a folder: refused before (it had written
    assert main(["reconstruct", t("cap.h5"), "--out", t("fig.h5")]) == 2         # fig.h5, then failed, exit 2)
    assert "the figure" in capsys.readouterr().err and not (tmp_path / "fig.h5").exists()
    assert ran == []
    assert main(["profiles", t("cap.h5"), "--out", t("prof.png")]) == 0               # PREFIX.png.csv ...
    assert main(["refocus", t("cap.h5"), "--slope", "0", "--out", t("planes.png")]) == 0
    assert len(ran) == 2


def test_a_recording_too_large_for_the_disk_is_refused_before_it_is_rendered(tmp_path, capsys):
    """simulate-sequence --fps 1e9 (a billion 16-bit frames) is refused naming the size and the disk's free space
    before a frame is rendered (it had written 1.25 GB in 20 s and gone on); --duration 0 by its name."""
    assert main(["simulate-sequence", "--fps", "1e9", "--duration", "1", "--out", str(tmp_path / "r.h5")]) == 2
    assert "GB free: a lower --fps or a shorter --duration" in capsys.readouterr().err
    assert main(["simulate-sequence", "--duration", "0", "--out", str(tmp_path / "r.h5")]) == 2
    assert "--duration must be positive" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_a_random_depth_scene_on_a_camera_too_small_for_it_is_refused_in_words(tmp_path, capsys):
    """simulate --scene depth on a 6 x 6-lenslet camera: its field cannot hold a flame of the smallest width; said so,
    where numpy's 'high - low < 0' had been the message."""
    cam = tmp_path / "tiny.toml"
    cam.write_text("[camera]\nn_rows = 6\nn_cols = 6\n")
    assert main(["simulate", "--camera", str(cam), "--scene", "depth", "--out", str(tmp_path / "t.npz")]) == 2
    assert "is too narrow for a flame of its smallest half-width" in capsys.readouterr().err


def test_simulate_says_where_its_npz_is(tmp_path, capsys):
    """simulate --out p.txt writes p.txt.npz (NumPy's name) and says so, where it had printed p.txt; nothing
    temporary is left."""
    cam = tmp_path / "small.toml"
    cam.write_text("[camera]\nn_rows = 12\nn_cols = 12\n")
    assert main(["simulate", "--camera", str(cam), "--scene", "point", "--rays-per-pixel", "1",
                 "--out", str(tmp_path / "p.txt")]) == 0
    assert f"-> {tmp_path / 'p.txt.npz'}" in capsys.readouterr().out
    assert sorted(f.name for f in tmp_path.iterdir()) == ["p.txt.npz", "small.toml"]


def test_ctrl_c_ends_with_one_line_and_130(capsys, monkeypatch):
    def interrupted(a):
        raise KeyboardInterrupt
    monkeypatch.setattr(cli.resolution, "cmd_resolution", interrupted)
    assert main(["resolution"]) == 130
    assert _one_error_line(capsys.readouterr().err) == "interrupted"


def test_failures_while_running_give_1_and_bad_input_2(capsys, monkeypatch):
    """A disk full (OSError) or a runtime failure: exit 1 in one line; a command's own refusal
    raised as SystemExit("message"): exit 2."""
    import errno

    def failing(exc):
        def cmd(a):
            raise exc
        return cmd
    for exc, code, text in ((OSError(errno.ENOSPC, "No space left on device", "out.h5"), 1,
                             "error: out.h5: No space left on device"),
                            (RuntimeError("the solver diverged"), 1, "error: the solver diverged"),
                            (SystemExit("error: give RAW"), 2, "error: give RAW"),
                            (ValueError("bad\nvalue"), 2, "error: bad value")):
        monkeypatch.setattr(cli.resolution, "cmd_resolution", failing(exc))
        assert main(["resolution"]) == code
        assert _one_error_line(capsys.readouterr().err) == text


def test_an_interrupted_write_leaves_no_temporary_file(tmp_path, monkeypatch):
    """Ctrl-C while a reconstruction's HDF5 or a text table is written: neither the output nor
    its temporary file is left (an older text file is kept)."""
    from lf_flame.config import atomic_write_text
    from lf_flame.tomo.solvers import Reconstruction
    from lf_flame.tomo.files import save_reconstruction

    class Stop:
        def __float__(self):
            raise KeyboardInterrupt
    rec = Reconstruction(planes=np.zeros((1, 2, 2)), depths_mm=np.zeros(1), sample_mm=np.ones((1, 2)),
                         residuals=[], solver="adjoint", settings={}, time_s=0.0)
    with pytest.raises(KeyboardInterrupt):
        save_reconstruction(tmp_path / "r.h5", rec, note=[Stop()])
    assert list(tmp_path.iterdir()) == []
    atomic_write_text(tmp_path / "t.md", "old")
    real = type(tmp_path).write_text

    def half_then_stop(self, text):
        real(self, text[:2])
        raise KeyboardInterrupt
    monkeypatch.setattr(type(tmp_path), "write_text", half_then_stop)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(tmp_path / "t.md", "new table")
    monkeypatch.undo()
    assert [p.name for p in tmp_path.iterdir()] == ["t.md"] and (tmp_path / "t.md").read_text() == "old"


@pytest.mark.parametrize("argv, option, text", [
    (["sequence", "x.h5", "--depth", "0", "--workers", "0", "--out", "o"], "--workers", "whole number >= 1"),
    (["dataset", "--data-config", "c.toml", "--scene", "shapes", "--slopes", "s.json", "--workers", "-2", "--out",
      "d.h5"], "--workers", "whole number >= 1"),
    (["reconstruct", "x.npz", "--iters", "0", "--out", "r.h5"], "--iters", "whole number >= 1"),
    (["sequence", "x.h5", "--route", "reconstruct-admm", "--iters", "0", "--out", "o"], "--iters",
     "whole number >= 1"),
    (["temperature", "x.npz", "--calibration", "bb.json", "--min-fraction", "-1", "--out", "t.h5"], "--min-fraction",
     "number from 0 to 1"),
    (["temperature", "x.npz", "--calibration", "bb.json", "--min-fraction", "nan", "--out", "t.h5"],
     "--min-fraction", "number from 0 to 1"),
    (["evaluate", "--dataset", "d.h5", "--model-dir", "m", "--results", "r", "--heldout", "-3", "--heldout-seed", "5"],
     "--heldout", "whole number >= 0"),
    (["reconstruct", "x.npz", "--saturation", "nan", "--out", "r.h5"], "--saturation", "positive level"),
    (["simulate", "--scene", "point", "--x", "inf", "--out", "p.npz"], "--x", "finite number"),
    (["simulate", "--scene", "flame", "--seed", "-1", "--out", "p.npz"], "--seed", "whole number >= 0"),
    (["simulate-sequence", "--seed", "-1", "--out", "r.h5"], "--seed", "whole number >= 0"),
    (["sequence", "x.h5", "--depth", "nan", "--out", "o"], "--depth", "finite number"),
    (["temperature", "x.npz", "--calibration", "bb.json", "--alpha", "nan", "--out", "t.h5"], "--alpha",
     "finite number"),
    (["temperature", "x.npz", "--calibration", "bb.json", "--saturation", "-1", "--out", "t.h5"], "--saturation",
     "positive level"),
])
def test_options_out_of_range_are_refused_by_their_own_name(argv, option, text, capsys):
    """Refused while the arguments are parsed (exit 2, before any file is read), the message
    naming the option as the user typed it (not the solver's internal 'fills and inner')."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: takes a {text}" in err and "fills" not in err, err


def test_options_in_range_parse():
    a = cli.build_parser().parse_args(["temperature", "x.npz", "--calibration", "c.json", "--min-fraction", "1",
                                       "--out", "t.h5"])
    assert a.min_fraction == 1.0
    a = cli.build_parser().parse_args(["sequence", "x.h5", "--workers", "2", "--iters", "1", "--out", "o"])
    assert (a.workers, a.iters) == (2, 1)


def test_solver_options_the_solver_does_not_use_are_refused(capsys):
    """reconstruct's --iters, --damp, --tv and --saturation refused where its solver does not use them, naming them
    and the solver: they had been taken (and printed: 'adjoint, 50 iterations') without changing a pixel."""
    for argv, text in ((["--solver", "adjoint", "--iters", "50"], "--iters is not used by the adjoint solver"),
                       (["--damp", "5"], "--damp is not used by the admm solver (it takes --iters, --tv)"),
                       (["--solver", "rl", "--tv", "3"], "--tv is not used by the rl solver"),
                       (["--solver", "learned", "--iters", "5", "--saturation", "none"],
                        "--iters and --saturation are not used by the learned solver (it takes none of them)")):
        assert main(["reconstruct", "x.npz", *argv, "--out", "r.h5"]) == 2, argv
        assert text in capsys.readouterr().err, argv


def test_a_depth_list_that_starts_below_zero_is_taken(monkeypatch):
    """``--depths -39.48,0`` as the docs write it (argparse had taken the list for an option: 'expected one
    argument'); a lone negative number and the '=' form as before."""
    seen = []
    monkeypatch.setattr(cli.volume, "cmd_reconstruct", lambda a: seen.append((a.depths, a.search_range)))
    monkeypatch.setattr(cli.temperature, "cmd_temperature", lambda a: seen.append(a.depths))
    assert main(["reconstruct", "x.npz", "--depths", "-39.48,0", "--search-range", "-5", "20", "--out", "r.h5"]) == 0
    assert main(["temperature", "x.npz", "--calibration", "c.json", "--depths", "-3, -1.5,2", "--out", "t.h5"]) == 0
    assert main(["reconstruct", "x.npz", "--depths=-1,2", "--out", "r.h5"]) == 0
    assert seen == [("-39.48,0", [-5.0, 20.0]), "-3, -1.5,2", ("-1,2", None)]


def test_sequence_refuses_planes_outside_the_cameras_range(tmp_path, capsys, monkeypatch):
    """``sequence --depth 500`` (or a slope of 5) is refused as reconstruct refuses it, naming
    the camera's imaging range, before any frame is processed."""
    import lf_flame.recordings.runner as runner
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.optics.depth_range import imaging_range_mm
    monkeypatch.setattr(runner, "run", lambda *a, **k: pytest.fail("the run started"))
    rec = tmp_path / "rec.h5"
    with h5py.File(rec, "w") as f:
        f["frames"] = np.zeros((2, 4, 4), np.uint16)
        f.attrs["fps"] = 100.0
    lo, hi = imaging_range_mm(PAPER_CAMERA)
    for planes, shown in ((["--depth", "500", "--depth", "0"], "+500"), (["--slope", "5"], "")):
        assert main(["sequence", str(rec), *planes, "--out", str(tmp_path / "o")]) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert f"planes at {shown}" in line and "lie outside what this camera can refocus" in line, line
        assert f"({lo:+.4g} .. {hi:+.4g} mm" in line
    assert not (tmp_path / "o").exists()


def test_refocus_and_simulate_refuse_planes_no_camera_images(tmp_path, capsys):
    """``refocus --depth 500`` (slope 4.4 on the paper camera) and ``--slope 40`` are refused as reconstruct refuses
    them (they were refocused, onto nothing), and so is a plane given twice (reconstruct solved two identical
    planes); ``simulate --depth -1000`` (the object behind the main lens, 1 m in
    front of the focus distance) is refused naming the depth (it stopped in a ZeroDivisionError)."""
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.optics.depth_range import imaging_range_mm
    views = tmp_path / "raw.npy"                                       # the paper camera's raw image
    np.save(views, np.random.default_rng(0).uniform(0.1, 0.5, PAPER_CAMERA.sensor_shape).astype(np.float32))
    lo, hi = imaging_range_mm(PAPER_CAMERA)
    for planes, shown in ((["--depth", "500", "--depth", "0"], f"planes at +500 mm lie outside what this camera can "
                           f"refocus ({lo:+.4g} .. {hi:+.4g} mm"), (["--slope", "40"], "planes at slopes +40 lie outside"),
                          (["--depth", "5", "--depth", "0", "--depth", "5"], "planes at +5 mm are given more than once")):
        assert main(["refocus", str(views), *planes, "--out", str(tmp_path / "r.npz")]) == 2
        line = _one_error_line(capsys.readouterr().err)
        assert shown in line, line
    assert not (tmp_path / "r.npz").exists()
    z = PAPER_CAMERA.focus_distance_mm
    assert main(["simulate", "--scene", "point", "--depth", str(-z - 1000), "--out", str(tmp_path / "p.npz")]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"--depth {-z - 1000:+g} mm puts the object" in line and "behind it" in line, line


class _Frames:
    """A stand-in for SimulatedSource: 6 frames of 4 x 5 pixels, frame i filled with i / 10; it
    counts the frames rendered and stops (Ctrl-C) at frame ``stop_at``."""

    sensor = None                           # monochrome

    def __init__(self, seed=0, stop_at=None):
        self.n_frames, self.seed, self.stop_at, self.rendered = 6, seed, stop_at, []
        self.camera = types.SimpleNamespace(sensor_shape=(4, 5), to_json=lambda: '{"camera": 1}')
        self.sequence = types.SimpleNamespace(fps=100.0, to_dict=lambda: {"seed": seed})

    def identity(self):
        return dict(kind="simulated", sequence={"seed": self.seed}, rays_per_pixel=1)

    def raw(self, i):
        if i == self.stop_at:
            raise KeyboardInterrupt
        self.rendered.append(i)
        return np.full((4, 5), (i + 1) / 10, np.float32)


def test_simulate_sequence_resumes_its_partial_file(tmp_path, capsys):
    """A recording stopped at frame 3 leaves OUT.partial with frames 0-2; the same run again
    renders only frames 3-5 (the file equals an uninterrupted run's), a run of other settings
    starts over and says so."""
    from lf_flame.recordings.sources import write_frames
    out = tmp_path / "rec.h5"
    with pytest.raises(KeyboardInterrupt):
        write_frames(out, _Frames(stop_at=3), progress=False)
    partial = tmp_path / "rec.h5.partial"
    assert not out.exists() and partial.exists()
    src = _Frames()
    write_frames(out, src, progress=False)
    assert src.rendered == [3, 4, 5] and not partial.exists()
    assert "resuming, 3 of 6 frames already written" in capsys.readouterr().out
    clean = _Frames()
    write_frames(tmp_path / "clean.h5", clean, progress=False)
    with h5py.File(out) as f, h5py.File(tmp_path / "clean.h5") as g:
        assert np.array_equal(f["frames"][:], g["frames"][:]) and "done" not in f
        assert dict(f.attrs) == dict(g.attrs)
    with pytest.raises(KeyboardInterrupt):
        write_frames(out, _Frames(stop_at=2), progress=False)
    other = _Frames(seed=1)
    write_frames(out, other, progress=False)
    assert other.rendered == list(range(6)) and "other settings" in capsys.readouterr().out


def test_a_fixed_recording_is_run_again_in_the_folder_of_its_failed_run(tmp_path, capsys, monkeypatch):
    """A run that failed on a bad frame leaves job.json and the chunks done; once the recording
    is fixed (same path, new size or time) the rerun starts over with a message and removes the
    stale chunks; other settings in a folder holding another run's chunks are still refused."""
    import lf_flame.recordings.runner as runner
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.recordings.job import SequenceJob
    from lf_flame.recordings.sources import open_source
    rec = tmp_path / "rec.h5"
    with h5py.File(rec, "w") as f:
        f["frames"] = np.zeros((4, 4, 4), np.float32)
    out = tmp_path / "out"

    def job(depth=0.0):
        src, _ = open_source(rec)
        return SequenceJob(src, PAPER_CAMERA, 100.0, (depth,), (PAPER_CAMERA.slope_for_depth(depth),), (None,),
                           chunk=2)

    calls = []

    def chunk(c, j):
        calls.append(c)
        if c == 1:
            raise ValueError("frame 2: frame holds NaN or inf")
        return dict(rows=[dict(frame=i, plane=0) for i in (2 * c, 2 * c + 1)], read_s=0, refocus_s=0, measure_s=0)
    monkeypatch.setattr(runner, "process_chunk", chunk)
    monkeypatch.setattr(runner, "_write_csv", lambda path, df: path.write_text("frame\n"))
    with pytest.raises(ValueError, match="frame 2"):
        runner.run(job(), out, progress=False)
    assert (out / "job.json").exists() and (out / "parts" / "chunk-00000.csv").exists()
    with h5py.File(rec, "r+") as f:                      # the frame fixed (and the file rewritten)
        f["extra"] = np.ones(1000)
    calls.clear()
    capsys.readouterr()
    with pytest.raises(ValueError, match="frame 2"):     # it starts over: chunk 0 again, then the stub fails
        runner.run(job(), out, progress=False)
    assert calls == [0, 1]
    assert f"{rec} changed since the run in {out}" in capsys.readouterr().out
    with pytest.raises(ValueError, match=r"holds a run with other settings \(job.json: depths_mm \[0.0\] there, "
                                         r"\[5.0\] now, slopes "):       # which setting differs, named
        runner.run(job(depth=5.0), out, progress=False)


def test_a_failed_run_without_a_chunk_done_does_not_block_another(tmp_path, capsys):
    from lf_flame.recordings.runner import _start_over_or_refuse
    (tmp_path / "parts").mkdir()
    old = json.dumps(dict(source=dict(kind="hdf5", path="/a.h5", size=1, mtime=1.0), depths_mm=[0.0]))
    new = json.dumps(dict(source=dict(kind="hdf5", path="/b.h5", size=1, mtime=1.0), depths_mm=[0.0]))
    _start_over_or_refuse(tmp_path, old, new)
    assert "no chunk done: starting over" in capsys.readouterr().out
    (tmp_path / "parts" / "chunk-00000.csv").write_text("frame\n")
    with pytest.raises(ValueError, match="other settings"):
        _start_over_or_refuse(tmp_path, old, new)
    assert (tmp_path / "parts" / "chunk-00000.csv").exists()


def test_calibration_json_gets_the_mode_of_a_plain_open(tmp_path):
    """write_calibration's file has the permissions a plain open() gives under the umask
    (0644 under 022, not a temporary file's 0600) and leaves no temporary file."""
    from lf_flame.temperature import pyrometry as P
    from lf_flame.optics.colour import library_sensor
    nikon = library_sensor()
    cal = P.fit_calibration(nikon, [2000.0], [float(P.model_ratio(nikon, 2000.0, alpha=0.0))])
    old = os.umask(0o022)
    try:
        path = P.write_calibration(tmp_path / "bb.json", cal)
        plain = tmp_path / "plain.json"
        plain.write_text("{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bb.json", "plain.json"]
    assert P.load_calibration(path) == cal
    (tmp_path / "bad.json").write_text("")
    with pytest.raises(ValueError, match="bad.json is not an lf_flame temperature calibration"):
        P.load_calibration(tmp_path / "bad.json")


def test_reading_names_the_damaged_file(tmp_path):
    from lf_flame.config import DamagedFileError, reading
    p = tmp_path / "x.npz"
    p.write_bytes(b"PK\x03\x04 not a whole zip")
    with pytest.raises(DamagedFileError, match=r"x.npz is not a readable .npz file: it is truncated or damaged"):
        with reading(p, ".npz file"):
            np.load(p)
    with pytest.raises(FileNotFoundError):                 # passes as it is: main says 'not found'
        with reading(tmp_path / "gone.npz"):
            np.load(tmp_path / "gone.npz")
    assert issubclass(DamagedFileError, ValueError)


def test_a_camera_given_that_differs_from_the_files_record_is_warned_of(tmp_path, capsys):
    """A simulated capture (and recording) records its camera; a camera file given that differs (here its focus
    distance 5 mm off: the lenslet images' spacing moves by 0.02 %, invisible in the image, every depth moves) is used,
    with a warning naming the fields; the same camera given again, none."""
    import warnings as w
    from lf_flame.optics.camera import PlenopticCamera
    (tmp_path / "cam.toml").write_text("[camera]\nn_rows = 30\nn_cols = 30\n")
    focus = PlenopticCamera().focus_distance_mm
    (tmp_path / "off.toml").write_text(f"[camera]\nn_rows = 30\nn_cols = 30\nfocus_distance_mm = {focus + 5}\n")
    raw = tmp_path / "p.npz"
    assert main(["simulate", "--scene", "point", "--data-config", str(tmp_path / "cam.toml"), "--rays-per-pixel", "1",
                 "--out", str(raw)]) == 0
    with pytest.warns(UserWarning, match=r"records the camera it was rendered with, and the camera given differs "
                                         r"\(focus_distance_mm " + f"{focus + 5}"):
        assert main(["refocus", str(raw), "--camera", str(tmp_path / "off.toml"), "--slope", "0",
                     "--out", str(tmp_path / "r.npz")]) == 0
    with w.catch_warnings():
        w.simplefilter("error", UserWarning)
        assert main(["refocus", str(raw), "--camera", str(tmp_path / "cam.toml"), "--slope", "0",
                     "--out", str(tmp_path / "r2.npz")]) == 0


def test_a_crop_of_a_perfect_grids_sensor_names_the_calibration_that_decodes_it():
    """An image a row short of a perfect grid's sensor is refused naming both sizes and how a crop is read (decoded
    with the white-image calibration of the same crop), as docs/own_camera.md says."""
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.real.lightfield import from_raw
    rows, cols = PAPER_CAMERA.sensor_shape
    with pytest.raises(ValueError, match=rf"shape \({rows - 1}, {cols}\) is not this camera's {rows} x {cols} px raw "
                                         r"image \(a crop of the sensor is decoded with the white-image calibration"):
        from_raw(np.zeros((rows - 1, cols), np.float32), PAPER_CAMERA, "crop.npy")


def test_dataset_refuses_the_slopes_of_another_camera(tmp_path, capsys):
    """slopes.json records the camera its slopes were found on, and dataset refuses it for another camera, naming the
    fields that differ (a new user's camera focused 26 mm further took the quick camera's slopes, 2.275 for 3.05, and
    rendered ground truth refocused off the objects' planes: SSIM 0.76-0.87 against the right one). The quick
    pipeline's test takes its own camera's slopes through the same check."""
    import dataclasses
    from pathlib import Path

    from lf_flame.config import load_data_config
    root = Path(__file__).resolve().parents[1]
    cfg = str(root / "data_gen" / "quick.toml")
    cam, _ = load_data_config(cfg)
    other = dataclasses.replace(cam, focus_distance_mm=cam.focus_distance_mm + 26.0)
    bad = tmp_path / "slopes.json"
    bad.write_text(json.dumps(dict(slopes=[3.05, 1.61, 0.0, -1.72], camera=json.loads(other.to_json()))))
    assert main(["dataset", "--data-config", cfg, "--scene", "flame", "--slopes", str(bad), "--out",
                 str(tmp_path / "d.h5"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds the slopes of another camera" in err and "focus_distance_mm" in err
    assert not (tmp_path / "d.h5").exists()


def test_slope_calibration_searches_beyond_the_shapes_analytic_slopes(tmp_path, capsys):
    """``slopes --data-config`` on a camera of 9 pixels per lenslet, where the +20 mm rectangle's analytic slope is
    3.80 lenslets per view: found there (it was pinned at the search's end, 3.000, and the dataset took it);
    ``--lo``/``--hi``, which this mode had ignored, are refused."""
    from lf_flame.config import load_data_config
    cfg = tmp_path / "n9.toml"
    cfg.write_text("[camera]\nn_rows = 48\nn_cols = 24\npixels_per_lenslet = 9\n\n[dataset]\n"
                   "n_samples = { shapes = 4, flame = 4 }\nrays_per_pixel = 1\ncalibration_rays_per_pixel = 4\n"
                   "seed = 1\nsplit = [0.5, 0.25, 0.25]\n")
    cam, _ = load_data_config(str(cfg))
    args = ["slopes", "--data-config", str(cfg), "--out", str(tmp_path / "s.json"), "--results", str(tmp_path / "r")]
    assert main(args + ["--lo", "-5"]) == 2 and "--lo go with RAW" in capsys.readouterr().err
    assert main(args) == 0
    slopes = json.loads((tmp_path / "s.json").read_text())["slopes"]
    assert slopes[0] == pytest.approx(cam.slope_for_depth(20.0), abs=0.1) and slopes[0] > 3.5, slopes


def test_simulate_refuses_placing_what_a_scene_draws_itself(tmp_path, capsys):
    """``simulate --scene depth --depth 50`` had rendered the depth scene with its drawn depths, the --depth ignored
    in silence; --depth, --x and --y place a point, and --depth and --x a volume's axis: elsewhere refused, naming
    them. A point at the defaults is still rendered."""
    from lf_flame.cli import main
    out = str(tmp_path / "s.npz")
    for argv, named in ((["--scene", "depth", "--depth", "50"], "--depth places"),
                        (["--scene", "volume", "--y", "2"], "--y places"),
                        (["--scene", "flame", "--x", "1", "--depth", "2"], "--depth and --x place")):
        capsys.readouterr()
        assert main(["simulate", *argv, "--rays-per-pixel", "1", "--out", out]) == 2
        assert named in capsys.readouterr().err, argv
    assert main(["simulate", "--scene", "point", "--rays-per-pixel", "1", "--out", out]) == 0


def test_slopes_and_refocus_warn_of_an_over_exposed_or_uniform_capture(tmp_path, capsys):
    """A capture clipped throughout had its slopes reported as a flame filling the field, with only a black level's
    warning: slopes and refocus warn of the clipped pixels and of views that carry no structure, as decode,
    reconstruct and profiles do."""
    from lf_flame.cli import main
    from lf_flame.optics.camera import PAPER_CAMERA
    np.save(tmp_path / "sat.npy", np.ones(PAPER_CAMERA.sensor_shape, np.float32))
    for argv in (["slopes", str(tmp_path / "sat.npy"), "--out-prefix", str(tmp_path / "s")],
                 ["refocus", str(tmp_path / "sat.npy"), "--depth", "0", "--out", str(tmp_path / "r.npz")]):
        capsys.readouterr()
        main(argv)
        out = capsys.readouterr()
        assert "of the lit pixels are clipped" in out.out + out.err and "carry no structure" in out.err, argv
