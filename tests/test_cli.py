"""The command line as a new user meets it: every option's default
in --help, a light import, what reconstruct leaves out, and files passed between commands."""
import argparse
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from lf_flame.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
#: Libraries only the commands that use them may import (seconds of start-up).
HEAVY = ("pylops", "pyproximal", "tensorflow", "keras", "dask", "numba", "matplotlib", "scipy", "skimage")


def _sub_parsers():
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


def test_every_option_shows_its_default_in_help(monkeypatch):
    """For every command, every option (or optional positional) with a default other than
    None shows it as '(default: VALUE)' in --help, and every argument has help text (those
    without a default say in it what happens without them)."""
    monkeypatch.setenv("COLUMNS", "100000")   # one line per option: no wrapping inside a value
    subs = _sub_parsers()
    assert {"simulate", "reconstruct", "profiles", "sequence", "refocus", "slopes"} <= set(subs)
    checked = 0
    for name, sp in subs.items():
        text = " ".join(sp.format_help().split())
        for act in sp._actions:
            if isinstance(act, argparse._HelpAction):
                continue
            assert act.help, f"{name} {act.dest}: no help text"
            if act.default is not None and act.default is not argparse.SUPPRESS:
                checked += 1
                assert f"(default: {act.default})" in text, f"{name} {act.option_strings or act.dest}: default " \
                                                            f"{act.default!r} not in its help"
    assert checked > 30


def test_help_names_reconstructs_planes_and_solver_defaults(monkeypatch):
    from lf_flame.simulate.scenes import PAPER_DEPTHS_MM
    from lf_flame.tomo.solvers import DEFAULT_ITERS, DEFAULT_SOLVER, DEFAULT_TV, EXACT_SOLVER
    monkeypatch.setenv("COLUMNS", "100000")
    text = _sub_parsers()["reconstruct"].format_help()
    assert ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) + " mm" in text
    assert all(f"{k} {v}" in text for k, v in DEFAULT_ITERS.items() if k not in ("adjoint", "admm"))
    assert f"(default: {EXACT_SOLVER}, traced: {DEFAULT_SOLVER})" in text and f"(default: {DEFAULT_TV})" in text


def test_importing_the_cli_loads_no_heavy_library():
    """`lf-flame --help` builds every parser without PyLops, TensorFlow, Dask, Numba,
    Matplotlib, SciPy or scikit-image: each command imports what it uses when it runs."""
    code = ("import sys; from lf_flame.cli import build_parser; build_parser(); "
            f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True,
                       env={"PYTHONPATH": str(ROOT), "PATH": ""})
    assert r.stdout.split() == [], f"importing lf_flame.cli loaded {r.stdout.split()}"


@pytest.fixture(scope="module")
def small_flame(tmp_path_factory):
    """A flame light field of a 41 x 41-lenslet camera (1 ray per pixel), as .npz and .png."""
    d = tmp_path_factory.mktemp("cli")
    (d / "small.toml").write_text("[camera]\nn_rows = 41\nn_cols = 41\n")
    for out in ("flame.npz", "flame.png"):
        assert main(["simulate", "--scene", "flame", "--data-config", str(d / "small.toml"), "--rays-per-pixel",
                     "1", "--out", str(d / out)]) == 0
    return d


def test_reconstruct_prints_the_saturated_pixels_it_leaves_out(small_flame, capsys):
    """The count printed is the image's pixels at or above the level; a pixel of 1 ray per pixel's render that stands
    out of its neighbours in the light field is a defect to the reader (repaired), whose samples the fit leaves out
    too and counts apart."""
    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.real.lightfield import from_raw
    raw = np.load(small_flame / "flame.npz")["raw"]
    level = 0.5
    lf = from_raw(raw, PlenopticCamera(n_rows=41, n_cols=41))
    n_sat = int((lf.views >= level).sum())
    assert 0 < n_sat < raw.size and lf.defective_pixels > 0
    out = small_flame / "sat.h5"
    assert main(["reconstruct", str(small_flame / "flame.npz"), "--solver", "fista", "--iters", "1",
                 "--rays-per-pixel", "1", "--saturation", str(level), "--depths", "scene", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"{n_sat} saturated pixels (at or above 0.5) left out of the fit" in printed
    assert f"{lf.defective_pixels} defective pixels" in printed
    with h5py.File(out) as f:
        assert json.loads(f.attrs["settings"])["n_saturated"] == int(((lf.views >= level) | lf.defects).sum())


def test_simulate_warns_of_objects_the_camera_cannot_show(tmp_path, capsys):
    """A point 40 mm behind the paper camera's focal plane (it refocuses -23 .. +26.8 mm) is rendered with a warning
    naming the range; a render with no light on the sensor is warned of (it was written without a word); a point at
    the focal plane is not."""
    from lf_flame.cli.optics import _render_warnings
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.simulate.scenes import point_scene
    assert main(["simulate", "--scene", "point", "--depth", "40", "--rays-per-pixel", "1", "--out",
                 str(tmp_path / "far.npz")]) == 0
    out = capsys.readouterr().out
    assert "warning: objects at +40 mm lie outside what this camera refocuses (-23" in out
    assert "holds no light" not in out
    _render_warnings(PAPER_CAMERA, point_scene(PAPER_CAMERA, 0.0), np.zeros((4, 4)))
    assert capsys.readouterr().out == "warning: the render holds no light: the scene's rays miss the sensor\n"
    _render_warnings(PAPER_CAMERA, point_scene(PAPER_CAMERA, 0.0), np.full((4, 4), 0.5))
    assert capsys.readouterr().out == ""


def test_simulates_png_reads_back_with_its_camera_and_reconstructs(small_flame, capsys):
    """`simulate --out x.png` then `reconstruct x.png`: the PNG carries the camera and the
    scene (the truth column), its values are the raw image's to 16 bits."""
    from lf_flame.cli._io import _load_raw
    raw_npz, cam_npz = _load_raw(small_flame / "flame.npz")
    raw_png, cam_png = _load_raw(small_flame / "flame.png")
    assert cam_png == cam_npz and raw_png.shape == raw_npz.shape
    assert np.max(np.abs(raw_png - np.clip(raw_npz, 0, 1))) <= 0.5 / 65535 + 1e-7
    assert main(["reconstruct", str(small_flame / "flame.png"), "--solver", "adjoint", "--rays-per-pixel", "1",
                 "--depths", "scene", "--out", str(small_flame / "png.h5")]) == 0
    out = capsys.readouterr().out
    assert "reconstructed 4 planes" in out and "(with the scene's truth)" in out
    assert (small_flame / "png.png").stat().st_size > 10_000


def test_the_default_reconstruction_imports_neither_pylops_nor_scipy_signal(small_flame):
    """Found depths and admm on the exact operator, ``--no-figure``, in a fresh interpreter: no PyLops,
    PyProximal, scipy.signal, scipy.stats, matplotlib or scikit-image's morphology (each command's start paid about
    a second for PyLops and scipy.signal, and 0.15-0.5 s for the morphology that skimage.measure.label loads at its
    first call), and no figure written."""
    import subprocess
    import sys
    out = small_flame / "nofig.h5"
    code = ("import sys; from lf_flame.cli import main; "
            f"assert main(['reconstruct', {str(small_flame / 'flame.npz')!r}, '--no-figure', '--out', {str(out)!r}]) "
            "== 0; print(sorted(m for m in ('pylops', 'pyproximal', 'scipy.signal', 'scipy.stats', 'matplotlib', "
            "'skimage.morphology') "
            "if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip().splitlines()[-1] == "[]", run.stdout
    assert "reconstructed" in run.stdout
    assert out.exists() and not out.with_suffix(".png").exists()


def test_the_program_exits_with_mains_status_and_its_objects_frozen_out_of_the_collector(monkeypatch):
    """``lf-flame`` (the entry point that setup.cfg names) and ``python -m lf_flame.cli`` run :func:`run`: it exits
    with the status :func:`main` returns, after :func:`gc.freeze` (the shutdown then skips the collector's passes);
    a bad input's status too."""
    import configparser
    import gc

    import lf_flame.cli as cli
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    assert "lf-flame = lf_flame.cli:run" in cfg["options.entry_points"]["console_scripts"]
    assert "run()" in (ROOT / "lf_flame" / "cli" / "__main__.py").read_text()
    monkeypatch.setattr(cli, "main", lambda argv=None: 2)
    try:
        assert gc.get_freeze_count() == 0
        with pytest.raises(SystemExit) as e:
            cli.run()
        assert e.value.code == 2 and gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
    r = subprocess.run([sys.executable, "-m", "lf_flame.cli", "reconstruct", "no-such-file.npz", "--out",
                        "x.h5"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == cli.EXIT_BAD_INPUT and "no-such-file.npz" in r.stderr


def test_admm_help_output_and_run_agree_on_its_fills(monkeypatch):
    """admm's iterations are its fills, a cap by the noise and grid that stops sooner once they
    converge: the help names the cap a run takes, and reconstruct's output (``iterations_note``)
    counts the fills that ran (counted here at the solver), not the cap. A quiet light field of
    one plane on a 12 x 12-lenslet camera, the 2 x 2 grid."""
    import re

    from lf_flame.tomo.files import iterations_note
    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.tomo.defaults import ADMM_KNOBS
    from lf_flame.tomo.exact import emission_operator
    from lf_flame.tomo.solvers import reconstruct
    monkeypatch.setenv("COLUMNS", "100000")
    text = " ".join(_sub_parsers()["reconstruct"].format_help().split())
    op = emission_operator(PlenopticCamera(n_rows=12, n_cols=12), [0.0], subsamples=2)
    _, R, C = op.dims
    yy, xx = np.mgrid[:R, :C]
    views = op.matvec(np.exp(-((yy - R / 2) ** 2 + (xx - C / 2) ** 2) / (2 * (R / 6) ** 2)).ravel())
    views = 0.8 * views.reshape(op.dimsd) / views.max()
    fills = []
    rec = reconstruct(views, op, "admm", callback=lambda k, x: fills.append(k))
    cap = ADMM_KNOBS[2, "quiet"]["fills"]
    assert rec.settings["iters"] == cap and re.search(rf"admm: .* at most {cap} \(quiet\) or \d+ \(noisy\) on the "
                                                      r"2 x 2 grid", text), text
    assert len(fills) == rec.settings["fills_run"] < cap          # converged before the cap
    assert iterations_note(rec) == f"{len(fills)} fills of at most {cap}, converged"
    rec = reconstruct(views, op, "admm", 2)                         # --iters 2: both run
    assert iterations_note(rec) == "2 fills"


def test_reconstruct_refuses_other_files_naming_what_it_reads(small_flame, capsys, tmp_path):
    """What another command writes and reconstruct cannot use: refused, exit 2, with the
    formats it reads named (not NumPy's allow_pickle message or a KeyError)."""
    stack = tmp_path / "stack.npz"
    assert main(["refocus", str(small_flame / "flame.npz"), "--slope", "0", "--out", str(stack)]) == 0
    assert np.load(stack)["depths_mm"].tolist() == [0.0]         # planes given by slope: their depths recorded
    capsys.readouterr()
    assert main(["refocus", str(small_flame / "flame.npz"), "--depth", "0", "--out", str(tmp_path / "d0.npz")]) == 0
    assert "at slopes +0 in" in capsys.readouterr().out             # the focal plane's slope, not "-0"
    text = tmp_path / "notes.txt"
    text.write_text("not an image")
    fake_npy = tmp_path / "fake.npy"
    fake_npy.write_text("not an array")
    h5 = tmp_path / "frames.h5"
    with h5py.File(h5, "w") as f:
        f["frames"] = np.zeros((2, 4, 4))
    capsys.readouterr()
    for path, problem in ((stack, "holds no raw image (its arrays: stack, slopes, depths_mm)"),
                          (text, "cannot read"), (fake_npy, "is not a NumPy array file"),
                          (h5, "is not a file of decoded views")):
        assert main(["reconstruct", str(path), "--out", str(tmp_path / "r.h5")]) == 2
        err = capsys.readouterr().err
        assert problem in err and ".npz from 'lf-flame simulate'" in err and "PNG or TIFF" in err, err
        assert "allow_pickle" not in err
    assert not (tmp_path / "r.h5").exists()


def test_volume_figure_draws_each_plane_at_its_depth_and_height():
    """The side views of reconstruct's volume figure: plane k's cells are centred on its
    depth (not spread over the depth range, up to half a spacing off) and span its own
    grid's height in mm."""
    from lf_flame.tomo.files import _side_mesh
    depths = np.array([-4.0, -3.0, -1.0, 0.5, 2.0, 3.0, 5.0])
    h = 0.1 + 0.002 * depths          # mm per sample: linear in depth, as the grids are
    X, Y = _side_mesh(depths, h, rows=10)
    assert X.shape == Y.shape == (11, 8)
    centres = (X[0, 1:] + X[0, :-1]) / 2
    np.testing.assert_allclose(centres[1:-1], depths[1:-1], atol=0.6)   # mid-points between neighbours
    assert np.all((X[0, :-1] < depths) & (depths < X[0, 1:]))
    np.testing.assert_allclose(X[0, [0, -1]], [depths[0] - 0.5, depths[-1] + 1.0])
    height = Y[0] - Y[-1]                     # top minus bottom edge at each depth edge
    np.testing.assert_allclose(np.interp(depths, X[0], height), 10 * h, rtol=1e-9)


def test_reconstruct_takes_the_finer_grid_by_default_and_the_lenslet_grid_when_asked(small_flame, capsys):
    """admm's default grid is 2 x 2 samples per lenslet (planes of twice the rows and columns in
    the HDF5); ``--subsamples 1`` keeps the lenslet grid; a traced operator always does."""
    shapes = {}
    for args in (["--subsamples", "auto"], ["--subsamples", "1"], ["--solver", "fista", "--rays-per-pixel", "1"]):
        out = small_flame / "sub.h5"
        assert main(["reconstruct", str(small_flame / "flame.npz"), "--iters", "2", "--depths", "scene", *args,
                     "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        with h5py.File(out) as f:
            shapes[args[1]] = f["planes"].shape
            assert ("2 x 2 samples per lenslet" in printed) == (f["planes"].shape[1] == 82)
            # the relative residual printed is the written planes' (admm's last fill's is of an older prediction)
            assert f"relative residual {json.loads(f.attrs['misfit'])['relative_residual']:.4f}" in printed, printed
    assert shapes == {"auto": (4, 82, 82), "1": (4, 41, 41), "fista": (4, 41, 41)}
    with pytest.raises(SystemExit):
        main(["reconstruct", str(small_flame / "flame.npz"), "--subsamples", "3", "--out", str(small_flame / "x.h5")])


def test_a_monochrome_render_of_a_colour_camera_is_read_as_monochrome(tmp_path, capsys):
    """A camera file naming a CFA, a scene that renders monochrome (``simulate --scene depth``, ``simulate-sequence``):
    the render says so and records it, and ``reconstruct`` and ``sequence`` given the same camera file read it as the
    monochrome light field it is, not as a mosaic to level (which would leave a quarter of it, the 'blue' samples,
    out of the fit)."""
    cam = tmp_path / "colour.toml"
    cam.write_text('[main_lens]\nfocal_length_mm = 80.0\nf_number = 8.0\nfocus_distance_mm = 400.0\n'
                   '[microlens_array]\npitch_um = 90.0\nfocal_length_mm = 0.9\n'
                   '[sensor]\npixel_size_um = 6.054\nrows = 300\ncols = 240\ncfa = "GRBG"\n')
    raw, rec = tmp_path / "depth.npz", tmp_path / "depth.h5"
    assert main(["simulate", "--camera", str(cam), "--scene", "depth", "--seed", "3", "--rays-per-pixel", "2",
                 "--out", str(raw)]) == 0
    printed = capsys.readouterr().out
    assert "rendered monochrome" in printed
    depths = [o["depth_offset_mm"] for o in json.loads(str(np.load(raw)["objects"]))]     # the flames drawn, said
    assert f"({len(depths)} flame" in printed and all(f"{d:+.2f}" in printed for d in depths)
    assert main(["reconstruct", str(raw), "--camera", str(cam), "--depth", "0", "--no-figure", "--out", str(rec)]) == 0
    assert "levelled" not in capsys.readouterr().out
    with h5py.File(rec, "r") as f:
        assert "monochrome" not in f.attrs
    frames = tmp_path / "frames.h5"
    assert main(["simulate-sequence", "--camera", str(cam), "--duration", "0.02", "--fps", "100", "--quiet",
                 "--out", str(frames)]) == 0
    assert "rendered monochrome" in capsys.readouterr().out
    assert main(["sequence", str(frames), "--camera", str(cam), "--depth", "0", "--route", "reconstruct-admm",
                 "--quiet", "--out", str(tmp_path / "seq")]) == 0
    out = capsys.readouterr().out
    assert "levelled" not in out and "(1 chunk processed, " in out and "seq/frames.csv" in out
    # a rerun that finds every chunk done says its speed is the earlier run's (it had read as this run's)
    assert main(["sequence", str(frames), "--camera", str(cam), "--depth", "0", "--route", "reconstruct-admm",
                 "--quiet", "--out", str(tmp_path / "seq")]) == 0
    assert "(every chunk done before: 1 chunk processed then, at " in capsys.readouterr().out


def test_a_volume_reaching_past_its_stack_is_warned_of(capsys):
    """A dense stack whose far plane holds as much light as its brightest (a flame 10 mm across whose axis stood 2 mm
    inside the stack's end: 3-D error 0.43 against 0.066 with the stack run further, without a word) is warned of,
    naming that end and --to; end planes at a quarter of the brightest (light a prior-free solve spreads over a stack
    that holds the flame) are not."""
    from lf_flame.cli.fit_notes import resolved_spacing_mm, stack_end_warning
    from lf_flame.tomo.solvers import Reconstruction
    assert resolved_spacing_mm({"spacing_interp_mm_10": [np.nan, 29.5, np.inf]}, 10.0) == 29.5   # NaN: not mapped
    assert resolved_spacing_mm({"spacing_interp_mm_10": [np.nan, np.inf]}, 10.0) == np.inf
    light = np.array([0.0, 0.5, 1.0, 0.8, 0.98])
    rec = Reconstruction(planes=light[:, None, None] * np.ones((5, 3, 3)), depths_mm=(-8.0, -4.0, 0.0, 4.0, 8.0),
                         sample_mm=((1.0, 1.0),) * 5, solver="admm")
    share = stack_end_warning(rec)
    err = capsys.readouterr().err
    assert share == pytest.approx({"near": 0.0, "far": 0.98})
    assert "the stack's far end (+8 mm) holds 98 % of its brightest plane's light" in err and "(--to)" in err
    assert "near end" not in err
    assert stack_end_warning(rec, resolved_mm=2.0) == share and "run the stack further" in capsys.readouterr().err
    # a camera whose data over the stack resolve no finer than half its span (a user's 16-view camera: 29.5 mm over
    # 30 mm): its light spreads along any stack, which running it further does not mend; said so
    for resolved, said in ((12.0, "resolve 12 mm apart at best"), (np.inf, "resolve no spacing within the stack")):
        assert stack_end_warning(rec, resolved_mm=resolved) == share
        err = capsys.readouterr().err
        assert said in err and "spreads along the stack whatever its length" in err and "(--to)" not in err
    rec.planes[[0, -1]] = 0.25
    assert stack_end_warning(rec) == pytest.approx({"near": 0.25, "far": 0.25}) and capsys.readouterr().err == ""
    assert stack_end_warning(rec, resolved_mm=np.inf) == pytest.approx({"near": 0.25, "far": 0.25})
    assert capsys.readouterr().err == ""


def test_simulate_notes_the_pixels_that_clip_the_sensor(capsys):
    """A render whose pixels reach the simulator's clipping level (1) says how many: the quick start's flame scene
    clipped 1,367 pixels without a word, and reconstruct then reported them left out of the fit."""
    from lf_flame.cli.optics import _render_warnings
    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.simulate.scenes_depth import random_depth_scene
    cam = PlenopticCamera(n_rows=60, n_cols=40)
    sc = random_depth_scene(cam, np.random.default_rng(1), n_flames=1)
    raw = np.full(cam.sensor_shape, 0.5, np.float32)
    _render_warnings(cam, sc, raw)
    assert "clip" not in capsys.readouterr().out
    raw.flat[:30] = 1.0
    _render_warnings(cam, sc, raw)
    assert "note: 30 pixels" in capsys.readouterr().out
