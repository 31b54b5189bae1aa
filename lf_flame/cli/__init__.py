"""``lf-flame``: the command line that the Make targets call. ``lf-flame --help``.

The argument parser and :func:`main`; the commands, one module per stage:
:mod:`.optics` (simulate, refocus, slopes), :mod:`.real` (calibrate, decode),
:mod:`.learning` (dataset, train, predict, evaluate, tables), :mod:`.volume` (reconstruct),
:mod:`.resolution` (the camera's depth-resolution map),
:mod:`.temperature` (calibrate-temperature, temperature: two-colour pyrometry),
:mod:`.profiles` and :mod:`.sequence` (recordings over time);
:mod:`._io` reads and writes their files.
"""
from __future__ import annotations

import argparse
import gc
import sys
import warnings
from pathlib import Path

from ..routes import LEARNED_ROUTES
from ..simulate.scenes import PAPER_DEPTHS_MM
from ..tomo.defaults import (ADMM_KNOBS, ADMM_QUIET, ADMM_SUBSAMPLES, ADMM_TV, DEFAULT_ITERS, DEFAULT_SOLVER,
                              DEFAULT_TV, EXACT_SOLVER, SOLVERS, SUBSAMPLES_MAX_PLANES, VOLUME_L1, VOLUME_MAX_PLANES,
                              VOLUME_PRIOR, VOLUME_PRIORS, VOLUME_STEP_MM, VOLUME_TV)
from ..tomo.resolution import AXES, CONDITIONS, DEFAULT_FAR_MM, DEFAULT_NEAR_MM, DEFAULT_SPACING_MM, FEATURE_SIZES_MM
from ._io import RAW_FORMATS, add_camera_args, add_search_arg, check_outputs, fraction, positive_int
from .learning import cmd_dataset, cmd_evaluate, cmd_predict, cmd_tables, cmd_train
from .optics import cmd_refocus, cmd_simulate, cmd_slopes
from .profiles import PROFILES_ROUTE, cmd_profiles
from .real import cmd_calibrate, cmd_decode
from .resolution import cmd_resolution
from .sequence import cmd_sequence, cmd_simulate_sequence
from .temperature import cmd_calibrate_temperature, cmd_temperature
from .volume import cmd_reconstruct

# The commands' modules import only NumPy at the top: each command imports the libraries
# it uses (PyLops, TensorFlow, Dask, Numba, Matplotlib, SciPy ...) when it runs, so
# ``lf-flame --help`` stays fast (tests/test_cli.py checks which modules it loads).


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Every option's help ends with its default, ``(default: ...)``; options without one
    (``None``) say in their help what happens without them."""

    def _get_help_string(self, action):
        if action.default is None:
            return action.help
        return super()._get_help_string(action)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose help (and its sub-commands') shows the defaults."""

    def __init__(self, *args, formatter_class=HelpFormatter, **kwargs):
        super().__init__(*args, formatter_class=formatter_class, **kwargs)


def add_figure_arg(s, what: str) -> None:
    """``--figure/--no-figure`` (``a.figure``, default True) of a command that draws ``what`` beside its output."""
    s.add_argument("--figure", action=argparse.BooleanOptionalAction, default=True,
                   help=f"the figure beside --out (.png: {what}); --no-figure skips it, and with it matplotlib's "
                        "import (about a second of a small camera's command)")


def _admm_fills(subsamples: int) -> str:
    """admm's cap on its fills on a grid of ``subsamples``, by the noise (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`)."""
    quiet, noisy = (ADMM_KNOBS[subsamples, k]["fills"] for k in ("quiet", "noisy"))
    return f"{quiet}" if quiet == noisy else f"{quiet} (quiet) or {noisy} (noisy)"


#: What admm's iterations are by default (``reconstruct --help``): its fills of the missing data, a cap by the
#: data's noise and the planes' grid, stopped sooner once they converge; ``reconstruct`` prints how many ran.
ADMM_FILLS_HELP = (f"admm: its fills of the missing data, by the data's noise and the grid: at most "
                   f"{_admm_fills(ADMM_SUBSAMPLES)} on the {ADMM_SUBSAMPLES} x {ADMM_SUBSAMPLES} grid, "
                   f"{_admm_fills(1)} on the lenslet grid, stopping sooner once they converge (the output says how "
                   "many ran); --iters N runs all N")


def _level_or_none(text: str):
    """A sensor level for ``--saturation``, None for 'none', or 'auto' (found in the image)."""
    t = text.strip().lower()
    return None if t == "none" else "auto" if t == "auto" else float(text)


#: What ``--saturation auto`` does (the help of the commands reading raw images).
AUTO_LEVEL = ("found in the image, where its pixels pile up at its largest value (a sensor clips at one level: a "
              "12-bit sensor's counts in a 16-bit file pile at 4095, or at 65520 shifted to the top bits), else 1.0 "
              "for an image in [0, 1] (integer files are read scaled by their type's range)")


def _bit_depth(text: str) -> int:
    """``--bit-depth``: an integer from 1 to 32."""
    try:
        bits = int(text)
    except ValueError:
        bits = 0
    if not 1 <= bits <= 32:
        raise argparse.ArgumentTypeError(f"--bit-depth takes an integer from 1 to 32. Received: {text!r}")
    return bits


def _subsamples(text: str):
    """``--subsamples``: 1 or 2, or None for 'auto'."""
    if text.lower() == "auto":
        return None
    if text not in ("1", "2"):
        raise argparse.ArgumentTypeError(f"--subsamples takes auto, 1 or 2. Received: {text!r}")
    return int(text)


def _bin_views(text: str):
    """``decode --bin``: a positive integer, or None for 'auto'."""
    if text.lower() == "auto":
        return None
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"--bin takes auto or a positive integer (pixels per view). Received: {text!r}")
    return int(text)


def _sequence_scene_args(s, simulate_only=False):
    """Arguments of a simulated recording (``simulate-sequence``; ``sequence --simulate``)."""
    pre = "--simulate: " if simulate_only else ""
    if not simulate_only:
        s.add_argument("--simulate", choices=["paper", "overlap"], default="paper",
                       help="paper: four flames at the paper's depths; overlap: two flames 20 mm apart, one "
                            "behind the other")
    s.add_argument("--fps", type=float, help=("frame rate, frames/s (a recording: default its file's; " if
                                              simulate_only else "frame rate, frames/s (") + "simulated: 500)")
    s.add_argument("--duration", type=float, default=1.0, help=pre + "length, s")
    s.add_argument("--freq", type=float, action="append", help=pre + "each flame's flicker frequency, Hz, farthest "
                   "first (repeatable; default drawn from 5-20 Hz)")
    s.add_argument("--noise", action="store_true", help=pre + "shot and read noise, 12 bits")
    s.add_argument("--seed", type=int, default=0, help=pre + "seed of the frequencies, phases and jitter")
    s.add_argument("--rays-per-pixel", type=int, default=4, help=pre + "rays traced per sensor pixel")
    s.add_argument("--camera", help="camera file (TOML: the datasheet tables of docs/own_camera.md, or a [camera] "
                   "table; default: the file's, else the paper's camera); with --calibration, the camera the frames "
                   "were taken with")
    s.add_argument("--data-config", help="TOML with a [camera] table (as --camera)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")


def build_parser() -> argparse.ArgumentParser:
    """The ``lf-flame`` argument parser: one sub-parser per command."""
    p = _Parser(prog="lf-flame", description="Light-field refocusing of burner flames: "
                "simulate, refocus, build datasets, train and evaluate the paper's model.")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="render a raw light-field image of a scene")
    s.add_argument("--scene", choices=["shapes", "flame", "point", "volume", "depth", "white", "colour-flame",
                                       "colour-depth", "furnace"], required=True,
                   help="shapes: the paper's four shapes (rectangle, triangle, circle, square); flame: four "
                        "flames; both at the paper's depths " + ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) +
                        " mm; point: one point of light (--depth, --y, --x); volume: a volumetric laminar flame "
                        "(a luminous sheath 10 mm across, at most 85 %% of the field, about a vertical axis through "
                        "--depth, default 0, in 32 layers; 'reconstruct --volume'); depth: 2-4 flames at random "
                        "depths, sizes and places (--seed), scaled to the camera (its depth of field and lenslet "
                        "footprint); white: a flat field, the white image that 'lf-flame calibrate' takes; seen "
                        "by a colour (Bayer) sensor, for 'lf-flame temperature': colour-flame: the four flames with "
                        "their temperature fields; colour-depth: the depth scene's flames, each with a drawn "
                        "temperature; furnace: a blackbody at --temperature filling the field, for "
                        "'lf-flame calibrate-temperature'. The colour sensor is the camera file's [sensor] cfa "
                        "(docs/own_camera.md), else colour-science's Nikon 5100 behind an RGGB CFA")
    s.add_argument("--out", required=True, help=".npz (raw, camera, objects, scene[, views]) or .png (the raw "
                   "image in 16 bits, clipped at 1, with the camera, objects and scene in its text); both read by "
                   "the commands that take a raw image")
    s.add_argument("--seed", type=int, default=0, help="seed of the scene's random variation and of the rays")
    s.add_argument("--rays-per-pixel", type=int, default=16, help="rays traced per sensor pixel (fewer: faster, "
                   "noisier)")
    s.add_argument("--data-config", "--camera", dest="data_config", help="camera file (the datasheet tables of "
                   "docs/own_camera.md) or a TOML with a [camera] table (default: the paper's camera); the scene's "
                   "depths are mm from its focus distance")
    s.add_argument("--nominal", action="store_true", help="the nominal scene (no random variation)")
    s.add_argument("--views", action="store_true", help="also store sub-aperture views (N, N, R, C)")
    s.add_argument("--crosstalk", action="store_true", help="add crosstalk through neighbouring lenslets")
    s.add_argument("--bit-depth", type=_bit_depth, help="quantise the raw image to this many bits, 1-32 (default: "
                   "not quantised)")
    s.add_argument("--temperature", type=float, help="furnace scene: the blackbody's temperature (K)")
    s.add_argument("--depth", type=float, default=0.0, help="point scene: depth offset (mm)")
    s.add_argument("--y", type=float, default=0.0, help="point scene: height (mm)")
    s.add_argument("--x", type=float, default=0.0, help="point scene: lateral position (mm)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("calibrate", help="calibrate a real camera's lenslet grid from a white image")
    s.add_argument("white", help="white (flat-field) image: PNG, TIFF, .npy or .npz")
    s.add_argument("--dark", help="dark frame, subtracted first")
    s.add_argument("--layout", choices=["auto", "square", "hex"], default="auto",
                   help="lenslet grid; auto: told by the angle between the white image's lattice vectors "
                        "(90°: square, 60°: hex)")
    s.add_argument("--camera-id", help="name of the camera, stored and checked by decode")
    s.add_argument("--camera", help="camera file (TOML): a [sensor] cfa marks the white image as a colour mosaic "
                                    "(also read from a simulated image's stored sensor)")
    s.add_argument("--out", required=True, help="calibration JSON")
    s.set_defaults(func=cmd_calibrate)

    s = sub.add_parser("decode", help="decode a real raw image into sub-aperture views with a calibration")
    s.add_argument("raw", help="raw light-field image: PNG, TIFF, .npy or .npz")
    s.add_argument("--calibration", required=True, help="JSON written by 'lf-flame calibrate'")
    s.add_argument("--white", help="white image (default: the calibration's, checked by its SHA-256)")
    s.add_argument("--dark", help="dark frame (default: the calibration's, if any)")
    s.add_argument("--no-white", action="store_true", help="no white-image normalisation")
    s.add_argument("--views", type=int, help="views per axis (default: as many as the lenslet image holds)")
    s.add_argument("--bin", default="auto", type=_bin_views,
                   help="pixels per view sample and axis, summed: views of a camera with larger pixels, as much light "
                        "and parallax, fewer views for the solvers ('auto': 1 up to 29 pixels per lenslet image, "
                        "else enough for at least 15 views, e.g. 3 for 48; 1 with --views or a colour sensor)")
    s.add_argument("--camera-id", help="refuse a calibration of another camera")
    s.add_argument("--camera", help="camera file (docs/own_camera.md): where its [sensor] names a colour filter array "
                   "(cfa), each view sample is taken from its nearest pixel and keeps that pixel's channel (the "
                   "views' channel map, which 'lf-flame temperature' reads); a raw image from 'lf-flame simulate' "
                   "with a colour sensor is decoded so without it")
    s.add_argument("--saturation", default="auto",
                   help="the sensor's clipping level in the raw image's units: the views' samples from pixels at or "
                        "above it are stored as 'clipped' (reconstruct leaves them out); auto: where the image's "
                        "pixels pile up at its largest value (a sensor clips at one level), else 1.0 when its values "
                        "are at most 1 (the simulator's), else the smallest 2**bits - 1 (bits 8, 10, 12, 14, 16) at "
                        "or above its maximum; 'none': no mask")
    s.add_argument("--out", required=True, help="HDF5 of the views (N, N, R, C)")
    s.set_defaults(func=cmd_decode)

    s = sub.add_parser("refocus", help="refocus a raw image (or decoded views) at one or more slopes")
    s.add_argument("raw", help=RAW_FORMATS + ", or VIEWS.h5 from decode")
    s.add_argument("--slope", type=float, action="append", help="lenslets per view (repeatable)")
    s.add_argument("--depth", type=float, action="append", help="instead of --slope: plane depth, mm from the "
                   "camera's focus distance (> 0 farther; repeatable); neither: the depths found in the views, as "
                   "'reconstruct' finds them")
    add_camera_args(s)
    s.add_argument("--method", choices=["shift-sum", "fourier"], default="shift-sum",
                   help="shift-and-sum of the views, or the Fourier slice")
    s.add_argument("--interpolation", choices=["bilinear", "nearest"], default="bilinear",
                   help="shift-sum only: bilinear, or whole-lenslet shifts")
    s.add_argument("--aperture", choices=["square", "circular"], default="circular",
                   help="views summed: all, or those inside the main lens's circular aperture")
    s.add_argument("--out", required=True, help=".npz (the planes as 'stack', with 'slopes' and 'depths_mm'), or "
                   ".png/.pdf/.svg: a figure of the planes in object-space mm at their depths, one colour bar")
    add_search_arg(s)
    s.set_defaults(func=cmd_refocus)

    s = sub.add_parser("slopes", help="sharpest slope of each object of a raw image (table and plot of the "
                       "sharpness curves); without RAW, calibrate the nominal scene of a data config")
    s.add_argument("raw", nargs="?", help=RAW_FORMATS + " (a simulated .npz: its objects' ROIs are used), "
                   "or VIEWS.h5 from decode")
    s.add_argument("--roi", type=int, nargs=4, action="append", metavar=("ROW0", "ROW1", "COL0", "COL1"),
                   help="region in lenslets (repeatable; default: the stored objects, else per depth the depth "
                   "search finds the bounding box of the lenslets that vote for it, else the whole image)")
    s.add_argument("--metric", choices=["tenengrad", "laplacian", "normvar"], default="tenengrad",
                   help="sharpness of a refocused region")
    s.add_argument("--method", choices=["fourier", "shift-sum"], default="fourier", help="refocusing of the search")
    s.add_argument("--lo", type=float, help="lowest slope searched, lenslets per view (default: the camera's "
                   "imaging range, |slope| <= 3 and object distances beyond 1.05 focal lengths)")
    s.add_argument("--hi", type=float, help="highest slope searched, lenslets per view (default: as --lo)")
    add_camera_args(s)
    s.add_argument("--aperture", choices=["square", "circular"], default="circular",
                   help="views summed: all, or those inside the main lens's circular aperture")
    s.add_argument("--out-prefix", help="write PREFIX.slopes.csv and PREFIX.slopes.png (default: beside RAW)")
    s.add_argument("--data-config", help="calibration mode: data config TOML")
    s.add_argument("--out", help="calibration mode: JSON of the slopes used for ground truth")
    s.add_argument("--results", help="calibration mode: folder for slopes.csv and slopes.png")
    s.set_defaults(func=cmd_slopes)

    s = sub.add_parser("dataset", help="generate (or resume) a dataset in HDF5")
    s.add_argument("--data-config", required=True, help="data config TOML (camera, sizes, seed, regime)")
    s.add_argument("--scene", choices=["shapes", "flame"], required=True, help="the paper's shapes or four flames")
    s.add_argument("--slopes", required=True, help="JSON written by 'lf-flame slopes'")
    s.add_argument("--regime", choices=["paper", "varied"],
                   help="scene variation (docs/scenes.md) instead of the data config's")
    s.add_argument("--out", required=True, help="dataset HDF5 (resumed when it exists)")
    s.add_argument("--shard", help="i/N: render only shard i of N (1 <= i <= N) beside --out; an unsharded "
                                   "run imports finished shards and renders the rest")
    s.add_argument("--scheduler", help="render on the Dask cluster at this address (tcp://...) or scheduler file")
    s.add_argument("--workers", type=positive_int, help="render on a local Dask cluster of this many worker "
                   "processes (>= 1)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_dataset)

    s = sub.add_parser("simulate-sequence", help="render a simulated recording of flickering flames to HDF5 "
                       "(frames (T, H, W), fps, camera and the truth)")
    _sequence_scene_args(s)
    s.add_argument("--out", required=True, help="HDF5 file")
    s.set_defaults(func=cmd_simulate_sequence)

    s = sub.add_parser("sequence", help="a flame recording: each plane's height, widths and intensity over time, "
                       "their spectra and dominant flicker frequency (serially or on Dask)")
    s.add_argument("input", nargs="?", help="HDF5 stack of raw frames (dataset 'frames' (T, H, W); optional "
                   "'times_s'), a multi-page TIFF (a high-speed camera's or ImageJ's stack: one frame per page; the "
                   "frame rate from its ImageJ frame interval, else --fps), or a folder of TIFF/PNG/.npy frames in "
                   "name order")
    s.add_argument("--simulate", choices=["paper", "overlap"], help="instead of INPUT: a simulated recording, "
                   "rendered frame by frame in the workers")
    _sequence_scene_args(s, simulate_only=True)
    s.add_argument("--depth", type=float, action="append", help="plane depth offset, mm (repeatable); default: a "
                   "simulated recording's flames' depths, else the depths found in the first frame, as 'reconstruct' "
                   "finds a capture's")
    s.add_argument("--slope", type=float, action="append", help="plane slope, lenslets per view (repeatable)")
    s.add_argument("--route", choices=["shift-sum", *(f"reconstruct-{k}" for k in SOLVERS)], default="shift-sum",
                   help="planes by shift-and-sum, or each plane's emission (as lf-flame reconstruct; its settings: "
                        "--iters, --tv, --saturation, --operator-rays)")
    s.add_argument("--iters", type=positive_int, help="reconstruct-*: iterations, >= 1 (default: the solver's, as "
                   "lf-flame reconstruct's --iters)")
    s.add_argument("--tv", type=float, default=None,
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
    s.add_argument("--white", help="real frames: white image for decoding")
    s.add_argument("--dark", help="real frames: dark frame")
    s.add_argument("--nperseg", type=int, help="Welch segment, frames (default: the whole record, bin 1/T)")
    s.add_argument("--chunk", type=int, default=16, help="frames per task (default: %(default)s)")
    s.add_argument("--workers", type=positive_int, help="a local Dask cluster of this many single-thread worker "
                   "processes, >= 1 (default: serial, Numba's threads)")
    s.add_argument("--scheduler", help="an existing Dask cluster: address (tcp://...) or scheduler file")
    s.add_argument("--out", required=True, help="output folder (resumed when it holds the same run)")
    add_search_arg(s)
    s.set_defaults(func=cmd_sequence)

    s = sub.add_parser("train", help="train the decoder on cached backbone features (resumable)")
    s.add_argument("--dataset", required=True, help="dataset HDF5 written by 'lf-flame dataset'")
    s.add_argument("--experiment-config", required=True, help="experiment config TOML (model and training)")
    s.add_argument("--out", required=True, help="model folder")
    s.add_argument("--input-size", help="ROWSxCOLS: backbone input size instead of the config's")
    s.add_argument("--time-budget-s", type=float, help="training time budget (s) instead of the config's")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("predict", help="the trained model's 4 refocused planes of a raw image, with its latency")
    s.add_argument("raw", help=RAW_FORMATS)
    s.add_argument("--model-dir", required=True, help="folder written by 'lf-flame train'")
    s.add_argument("--out", required=True, help=".npz (stack (4, R, C), latency_s) or .png (planes side by side)")
    s.add_argument("--repeat", type=int, default=5, help="timed calls after the warm-up")
    s.add_argument("--route", choices=list(LEARNED_ROUTES), default="network",
                   help="the trained network, or one of its yardsticks saved beside it")
    s.set_defaults(func=cmd_predict)

    s = sub.add_parser("profiles", help="flame diagnostics per plane: height, widths, centroid, intensity, "
                       "axial and radial profiles in object-space mm (CSV and figure)")
    s.add_argument("raw", help=RAW_FORMATS + ", or views .h5 from 'lf-flame decode' (the truth is marked when the "
                   "flames' objects are known: 'simulate --scene flame' .npz, dataset samples)")
    s.add_argument("--route", choices=["ground-truth", "shift-sum", "shift-sum-nearest", "fourier",
                                       *LEARNED_ROUTES, *(f"reconstruct-{k}" for k in SOLVERS)],
                   default=PROFILES_ROUTE, help="how the planes are made. reconstruct-SOLVER: each plane's emission "
                   "(lf-flame reconstruct, the solver's default iterations; admm's finer grid averaged to the "
                   "lenslets); the default, reconstruct-admm, measured every flame height of 'simulate --scene "
                   "flame' (seeds 0-2) within 0.21 mm, where refocused planes carry the other flames' blur (shift-"
                   "sum: the +20 mm flame of seed 0 measured 13 mm short, flagged untrusted). shift-sum, "
                   "shift-sum-nearest, fourier: refocused planes (faster; reconstruct-adjoint is plain refocusing "
                   "too); ground-truth: a dataset's stored planes; learned routes need --model-dir")
    s.add_argument("--model-dir", help="folder written by 'lf-flame train' (learned routes)")
    s.add_argument("--slope", type=float, action="append",
                   help="refocusing routes: one per plane (repeatable); default: the dataset's, else the analytic "
                   "slopes of the depths")
    s.add_argument("--depth", type=float, action="append",
                   help="a plane's depth, mm from the focus distance (repeatable; default: the flames' when RAW "
                        "stores them, a dataset sample's the paper's four, else the depths found in the views, as "
                        "'reconstruct --depths auto' finds them)")
    add_camera_args(s)
    s.add_argument("--out", required=True, help="PREFIX: writes PREFIX.csv (one row per plane), PREFIX.axial.csv "
                                               "and PREFIX.png")
    add_figure_arg(s, "each plane with its height, widths and profiles marked")
    add_search_arg(s)
    s.set_defaults(func=cmd_profiles)

    s = sub.add_parser("reconstruct", help="each plane's emission from one light field (3-D reconstruction with "
                       "the simulator as the forward operator) -> HDF5 and a figure")
    s.add_argument("raw", help=RAW_FORMATS + ", or views .h5 from 'lf-flame decode'")
    s.add_argument("--depth", type=float, action="append",
                   help="plane depth (mm from the focal plane; repeatable). Default: --depths auto")
    s.add_argument("--depths", default=None,
                   help="the planes: 'auto' (the default when neither --depth nor --slope is given) finds the depths "
                        "that hold emission from the views (depth from focus per region, several per region where "
                        "flames stand one behind another; lf_flame.tomo.depth) and solves on them, with admm unless "
                        "--solver says otherwise, writing each found depth and its uncertainty into the HDF5; "
                        "'scene': the depths of the objects that 'lf-flame simulate' stored (.npz or .png); 'paper': "
                        "the paper's four planes, " + ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) + " mm; or "
                        "depths in mm separated by commas")
    s.add_argument("--slope", type=float, action="append", help="plane slope instead of a depth (repeatable)")
    s.add_argument("--solver", choices=list(SOLVERS) + ["learned"],
                   help=f"the default is the one chosen on validation renders: {EXACT_SOLVER} on the exact operator, "
                        f"{DEFAULT_SOLVER} on a traced one (--rays-per-pixel); adjoint: plain refocusing through "
                        f"the operator's rays; learned: a trained network on a one-pass Wiener start (lenslet grid; "
                        f"--model; make train-reconstructor) (default: {EXACT_SOLVER}, traced: {DEFAULT_SOLVER})")
    s.add_argument("--model", default=None,
                   help="--solver learned: the folder of a reconstructor trained for this camera (default: "
                        "models/reconstructor/paper, make train-reconstructor)")
    s.add_argument("--iters", type=positive_int, help="iterations, >= 1 (default: the solver's, chosen on validation "
                   "renders: " + ", ".join(f"{k} {v}" for k, v in DEFAULT_ITERS.items() if k not in ("adjoint", "admm"))
                   + "; " + ADMM_FILLS_HELP + "; adjoint: none)")
    s.add_argument("--damp", type=float, default=0.0, help="LSQR damping (Tikhonov)")
    s.add_argument("--tv", type=float, default=None, help=f"TV weight of pd-tv (default: {DEFAULT_TV}) or of admm "
                   f"(default by the light field's noise and the grid: on {ADMM_SUBSAMPLES} x {ADMM_SUBSAMPLES} samples "
                   f"per lenslet {ADMM_KNOBS[ADMM_SUBSAMPLES, 'quiet']['tv']} on quiet data, "
                   f"{ADMM_KNOBS[ADMM_SUBSAMPLES, 'noisy']['tv']} on noisy; on the lenslet grid "
                   f"{ADMM_QUIET['tv']} and {ADMM_TV})")
    s.add_argument("--subsamples", type=_subsamples, default=None,
                   help="samples per lenslet and axis of the planes' grid on the exact operator: 1 (the lenslet grid) "
                        "or 2 (detail finer than a lenslet, seen off focus in the views' parallax; 4x the unknowns). "
                        f"Default 'auto': {ADMM_SUBSAMPLES} for admm on at most {SUBSAMPLES_MAX_PLANES} planes, else 1")
    s.add_argument("--support", action="store_true",
                   help="hold every found plane's emission to the regions its depth was found in (admm, found "
                        "depths). Without it only planes within 3 lenslets of parallax of each other are held so, where "
                        "they meet (their emission would otherwise split between them); docs/own_camera.md")
    s.add_argument("--saturation", type=_level_or_none, default=argparse.SUPPRESS,
                   help="the sensor's clipping level in the views' units: pixels at or above it are left out of the "
                        "fit ('none': fit every pixel; default auto: " + AUTO_LEVEL + "). Decoded views take only "
                        "'none' (fit every sample): they carry their clipped samples ('lf-flame decode "
                        "--saturation')")
    add_camera_args(s)
    s.add_argument("--rays-per-pixel", type=int, default=None,
                   help="rays per pixel of a traced forward operator (the reference; default: the exact operator "
                        "where the camera is a perfect lenslet grid, else 4 rays)")
    s.add_argument("--volume", action="store_true",
                   help="a volume: a dense stack every --step mm from --from to --to (mm from the focal plane) on the "
                        "exact operator's lenslet grid, with a prior (--prior), and the depth resolution the stack "
                        "carries for the data alone (lf_flame.tomo.volume)")
    s.add_argument("--from", dest="near", type=float, help="--volume: the nearest plane (mm)")
    s.add_argument("--to", dest="far", type=float, help="--volume: the farthest plane (mm)")
    s.add_argument("--step", type=float, default=VOLUME_STEP_MM, help=f"--volume: plane spacing (mm; at most "
                   f"{VOLUME_MAX_PLANES} planes)")
    s.add_argument("--prior", choices=list(VOLUME_PRIORS), default=VOLUME_PRIOR,
                   help=f"--volume: none (admm by the data's noise), tv (admm with TV per plane, weight --tv, "
                        f"default {VOLUME_TV['quiet']:g} on quiet data, {VOLUME_TV['noisy']:g} on noisy), sparse (admm "
                        f"with an l1 weight, --l1, default {VOLUME_L1['quiet']:g} of the weight that zeroes every "
                        f"plane), axisymmetric (a laminar flame's e(r, y) about a vertical axis found from the data: "
                        f"for laminar flames)")
    s.add_argument("--l1", type=float, default=None, help="--volume --prior sparse: the l1 weight in [0, 1)")
    s.add_argument("--out", required=True, help="volume.h5 (planes, depths, mm per sample, settings, residuals); "
                                               "the figure goes beside it as .png")
    add_figure_arg(s, "each plane beside its refocused plane and, for a simulated scene, the truth")
    add_search_arg(s)
    s.set_defaults(func=cmd_reconstruct)

    def sensor_args(s, calibration_default):
        s.add_argument("--sensor", help="camera sensitivities (a name of colour-science's MSDS_CAMERA_SENSITIVITIES, "
                       "e.g. 'Nikon 5100 (NPL)'); default: the image's stored sensor record"
                       + (", else the calibration's" if calibration_default else "") + ", else Nikon 5100 (NPL)")
        s.add_argument("--cfa", choices=["RGGB", "BGGR", "GRBG", "GBRG"], help="colour filter array (default: as "
                       "--sensor)")
        s.add_argument("--cfa-phase", type=int, nargs=2, metavar=("ROW", "COL"),
                       help="tile row and column (0 or 1) of pixel (0, 0) (default: as --sensor, else 0 0)")

    s = sub.add_parser("calibrate-temperature", help="two-colour temperature calibration (the channels' gain "
                       "ratio) from raw images of a blackbody (furnace) at known temperatures -> JSON")
    s.add_argument("images", nargs="+", help="raw colour images of a blackbody filling the field: " + RAW_FORMATS
                   + "; a camera whose lenslet grid is not perfect (rotated, hexagonal, a pitch of no whole number of "
                   "pixels): its images decoded with their channels apart ('lf-flame decode --camera cam.toml')")
    s.add_argument("--temperature", type=float, action="append", help="each image's temperature, K, in the images' "
                   "order (repeatable; one per image)")
    s.add_argument("--channels", default="R,G", help="numerator and denominator channels of the ratio")
    sensor_args(s, False)
    s.add_argument("--out", required=True, help="calibration JSON (read by 'lf-flame temperature')")
    s.set_defaults(func=cmd_calibrate_temperature)

    s = sub.add_parser("temperature", help="each plane's temperature map (K) from one colour light field by "
                       "two-colour pyrometry -> HDF5 and a figure")
    s.add_argument("raw", help="raw colour image (the CFA's mosaic): " + RAW_FORMATS + "; or VIEWS.h5 of a colour "
                   "capture decoded with its channels apart ('lf-flame decode --camera cam.toml') with --camera")
    s.add_argument("--calibration", required=True, help="JSON of 'lf-flame calibrate-temperature'; refused when "
                   "made for another sensor or CFA")
    s.add_argument("--camera", help="camera file (docs/own_camera.md) of decoded views (VIEWS.h5), or of a raw image "
                   "that stores none")
    s.add_argument("--grid-calibration", help="the white-image calibration JSON of 'lf-flame calibrate' (--calibration "
                   "is the blackbody's here): a raw capture is decoded with it, its channels apart, as 'lf-flame "
                   "decode --camera' decodes it")
    s.add_argument("--depth", type=float, action="append", help="plane depth (mm from the focal plane; repeatable). "
                   "Default: --depths auto")
    s.add_argument("--depths", default=None, help="'auto' (default): the depths holding emission found by depth from "
                   "focus on the calibration's two channels interpolated and summed; 'scene', 'paper', or depths in "
                   "mm separated by commas (as 'lf-flame reconstruct')")
    s.add_argument("--slope", type=float, action="append", help="plane slope instead of a depth (repeatable)")
    s.add_argument("--route", choices=["admm-cfa-matched", "admm-cfa", "admm-cfa-smooth", "refocus-cfa"],
                   default="admm-cfa-matched",
                   help="each channel's emission: the exact operator's admm on its own pixels (the CFA as a "
                        "missing-data mask) on a 2 x 2 grid per lenslet, re-imaged and solved again on the other "
                        "channel's pixels so that both channels' resolution matches, its settings and ratio "
                        "filter by the light field's noise (decoded captures: their own); admm on its own pixels "
                        "alone, unsmoothed or smoothed by 0.7 lenslet; or each channel's pixels refocused (a "
                        "square grid's only) (results/temperature.md)")
    s.add_argument("--min-fraction", type=fraction, default=0.1, help="pixels whose two channels' emission is below "
                   "this fraction (0 to 1) of their plane's peak get no temperature (counted as dim)")
    s.add_argument("--alpha", type=float, default=1.39, help="emissivity exponent of the source, eps ~ lambda^-alpha "
                   "(soot: 1.39, Hottel & Broughton; 0: a blackbody)")
    s.add_argument("--saturation", type=_level_or_none, default="auto", help="the sensor's clipping level of a raw "
                   "image: pixels at or above it are left out of the fit ('none': fit every pixel; default "
                   + "auto: " + AUTO_LEVEL + ")")
    sensor_args(s, True)
    s.add_argument("--out", required=True, help="T.h5: temperature_k, valid, dim (plane, row, col), emission, "
                   "depths_mm, counts, provenance; the figure goes beside it as .png")
    add_figure_arg(s, "each plane's temperature map in mm, one colour bar in K")
    add_search_arg(s)
    s.set_defaults(func=cmd_temperature)

    s = sub.add_parser("resolution", help="the camera's depth-resolution map: the smallest plane spacing that "
                       "the light field resolves against feature size, at stated condition numbers (from the exact "
                       "operator's per-frequency normal matrices of a dense stack)")
    s.add_argument("--camera", help="camera file: the datasheet tables of docs/own_camera.md, or a [camera] table "
                   "(default: the paper's camera)")
    s.add_argument("--near", type=float, default=DEFAULT_NEAR_MM, help="nearest plane of the stack, mm from the "
                   "focal plane (> 0 farther)")
    s.add_argument("--far", type=float, default=DEFAULT_FAR_MM, help="farthest plane, mm")
    s.add_argument("--spacing", type=float, default=DEFAULT_SPACING_MM, help="the stack's plane spacing, mm")
    s.add_argument("--condition", type=float, nargs="+", default=list(CONDITIONS),
                   help="condition numbers of the two planes' normal block (>= 1)")
    s.add_argument("--feature", type=float, nargs="+", default=list(FEATURE_SIZES_MM),
                   help="feature sizes, half a period, mm")
    s.add_argument("--axis", choices=list(AXES), default="rows", help="direction of the lateral frequency")
    s.add_argument("--out", help="PREFIX: also write PREFIX.csv, PREFIX.md and PREFIX.png (default: print only)")
    s.set_defaults(func=cmd_resolution)

    s = sub.add_parser("evaluate", help="SSIM/PSNR per plane on the test split, table and figure")
    s.add_argument("--dataset", required=True, help="dataset HDF5 written by 'lf-flame dataset'")
    s.add_argument("--model-dir", required=True, help="folder written by 'lf-flame train'")
    s.add_argument("--results", required=True, help="folder for the table (CSV) and figure")
    s.add_argument("--heldout", type=int, default=0,
                   help="also score a second held-out set of this many samples, drawn with --heldout-seed")
    s.add_argument("--heldout-seed", type=int, default=None,
                   help="seed of the second held-out set: needed with --heldout, not the dataset's seed")
    s.set_defaults(func=cmd_evaluate)

    s = sub.add_parser("tables", help="collect Tables I and II, slopes and stage times into tables.md")
    s.add_argument("--results", required=True, help="results folder: reads the evaluations, writes tables.md")
    s.add_argument("--data-dir", required=True, help="folder of the datasets and slopes.json")
    s.add_argument("--model-dir", required=True, help="folder of the trained models")
    s.set_defaults(func=cmd_tables)
    return p


#: Exit statuses: done; a failure while running (a full disk, a device error, out of memory); bad input
#: (options, missing or damaged files, outputs that cannot be written: argparse's refusals exit so too);
#: stopped by Ctrl-C (128 + SIGINT, as the shells report it).
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
#: How Python writes a warning (file, line, source): kept for the warnings of other packages.
_DEFAULT_FORMAT = warnings.formatwarning
#: The errors of the user's paths (bad input): a file missing or unreadable, a file where a folder must be.
PATH_ERRORS = (FileNotFoundError, PermissionError, NotADirectoryError, IsADirectoryError, FileExistsError)
#: Failures while running (reported on one line; any other exception is a bug: its traceback is shown).
RUN_ERRORS = (OSError, RuntimeError, MemoryError, FloatingPointError)


def _message(e: BaseException) -> str:
    """An exception as one line: an OS error's file and reason, else its text (or its kind)."""
    if isinstance(e, OSError) and e.filename and e.strerror:
        return f"{e.filename}: {e.strerror}"
    text = " ".join(str(e).split())
    return text or {MemoryError: "out of memory"}.get(type(e), type(e).__name__)


def main(argv=None) -> int:
    """Run one ``lf-flame`` command and return its exit status (:data:`EXIT_OK` ...).

    The outputs' folders are checked first (:func:`~lf_flame.cli._io.check_outputs`); bad
    input (``ValueError``, :data:`PATH_ERRORS`, a command's ``SystemExit("message")``) gives
    :data:`EXIT_BAD_INPUT`, a failure while running (:data:`RUN_ERRORS`) :data:`EXIT_FAILED`,
    Ctrl-C :data:`EXIT_INTERRUPTED`, each with one line on stderr; the writers leave no
    half-written output (temporary file, then renamed).
    """
    a = build_parser().parse_args(argv)
    default_format = warnings.formatwarning
    warnings.formatwarning = _format_warning
    try:
        check_outputs(a)
        a.func(a)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, *PATH_ERRORS) as e:
        print(f"error: {_message(e)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except SystemExit as e:
        if not isinstance(e.code, str):
            raise
        print(e.code if e.code.startswith("error: ") else f"error: {e.code}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RUN_ERRORS as e:
        print(f"error: {_message(e)}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        warnings.formatwarning = default_format
    return EXIT_OK


def run() -> None:
    """The ``lf-flame`` program (and ``python -m lf_flame.cli``): :func:`main` on ``sys.argv``, then the
    interpreter's exit with its status.

    Before exiting, every object is frozen out of the garbage collector (:func:`gc.freeze`): the interpreter's
    shutdown then tears down its modules without the collector's passes over the 100,000-odd objects that
    Numba, SciPy and the command left, 0.3 s of a 2.5 s ``reconstruct`` on 2 cores. Finalizers, ``atexit``
    handlers and file closes run as before.
    """
    status = main()
    gc.freeze()
    sys.exit(status)


def _format_warning(message, category, filename, lineno, line=None) -> str:
    """A warning of the package's own as one line for the command's user (``warning: ...``); any other as
    Python writes it (file, line and source)."""
    if Path(filename).resolve().is_relative_to(Path(__file__).resolve().parents[1]):
        return f"warning: {message}\n"
    return _DEFAULT_FORMAT(message, category, filename, lineno, line)
