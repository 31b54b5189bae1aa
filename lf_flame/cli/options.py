"""The command line's options (:mod:`lf_flame.cli`): their checks, made as they are parsed (numbers, fractions,
levels) or before any work (outputs that cannot be written or would overwrite an input), and the options several
commands share (the search range, the camera files, the figure). Serves every command group.
"""
from __future__ import annotations

import argparse
import math
import re
from pathlib import Path


# ---- the options' checks, made before any work ---------------------------------------
def _whole_number(text: str, least: int) -> int:
    """``text`` as a whole number >= ``least``, for an argparse ``type``.

    Raises
    ------
    argparse.ArgumentTypeError
        Anything else; argparse names the option and exits with status 2.
    """
    import argparse
    try:
        n = int(text)
    except ValueError:
        n = least - 1
    if n < least:
        raise argparse.ArgumentTypeError(f"takes a whole number >= {least}. Received: {text!r}")
    return n


def positive_int(text: str) -> int:
    """An argparse ``type``: a whole number >= 1 (``--workers``, ``--iters``; :func:`_whole_number`)."""
    return _whole_number(text, 1)


def count(text: str) -> int:
    """An argparse ``type``: a whole number >= 0 (``evaluate --heldout``; :func:`_whole_number`)."""
    return _whole_number(text, 0)


def finite(text: str) -> float:
    """An argparse ``type``: a finite number (every number option: NaN and inf had reached the work, where they
    stopped on messages that named no option, 'cannot convert float infinity to integer', or were taken).

    Raises
    ------
    argparse.ArgumentTypeError
        NaN, inf or not a number; argparse names the option and exits with status 2.
    """
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"takes a finite number. Received: {text!r}")
    return v


def fraction(text: str) -> float:
    """An argparse ``type``: a number from 0 to 1 (``--min-fraction``).

    Raises
    ------
    argparse.ArgumentTypeError
        Anything else (NaN included); argparse names the option and exits with status 2.
    """
    import argparse
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"takes a number from 0 to 1. Received: {text!r}")
    return v


#: The options (argparse ``dest``) naming what a command writes: a file, a folder or a prefix.
OUTPUT_OPTIONS = ("out", "out_prefix", "results")


def check_output(path) -> None:
    """Refuse an output that cannot be written, before the work that would fill it.

    The folder that will hold ``path`` (``path`` itself when it is an existing folder) must
    be writable or creatable: its nearest existing ancestor must be a folder that this
    process may write into.

    Parameters
    ----------
    path : path-like
        An output file, folder or prefix.

    Raises
    ------
    ValueError
        A file stands where a folder of the path must be, or the folder is not writable;
        the message names the path and the culprit.
    """
    import os
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    q = folder.absolute()
    while not q.exists() and q != q.parent:
        q = q.parent
    if not q.is_dir():
        raise ValueError(f"cannot write {p}: {q} is a file, not a folder")
    if not os.access(q, os.W_OK | os.X_OK):
        raise ValueError(f"cannot write {p}: the folder {q} is not writable")


def _input_paths(a) -> list[Path]:
    """The files that a command's other options name and that exist (``FILE.h5:INDEX`` as ``FILE.h5``); folders are
    not (a model folder and a results folder may be one)."""
    out = []
    for k, v in vars(a).items():
        if k in OUTPUT_OPTIONS:
            continue
        for x in v if isinstance(v, (list, tuple)) else [v]:
            if isinstance(x, (str, Path)) and str(x):
                q = Path(re.sub(r":\d+$", "", str(x)))
                try:
                    is_file = q.is_file()
                except OSError:                       # a value no path can be (a long --depths list: name too long)
                    is_file = False
                if is_file:
                    out.append(q)
    return out


def _same(p: Path, q: Path) -> bool:
    import os
    return os.path.samefile(p, q) if p.exists() and q.exists() else p.absolute() == q.absolute()


#: Suffixes dropped from the ``--out PREFIX`` of a command that writes PREFIX.csv, PREFIX.md, PREFIX.png ...
#: (``profiles``, ``resolution``): ``--out r.csv`` had written ``r.csv.csv``.
PREFIX_SUFFIXES = (".csv", ".md", ".png")


def check_outputs(a) -> None:
    """:func:`check_output` on each of a command's outputs (:data:`OUTPUT_OPTIONS` in ``a``; an ``--out PREFIX`` named
    as one of its files loses that suffix, :data:`PREFIX_SUFFIXES`), and refuse an output that is one of its inputs,
    or where its figure would be written (``--out X.png`` of a command that writes the figure beside its HDF5 as
    ``X.png``), where the input or the result would be overwritten.

    Raises
    ------
    ValueError
        As :func:`check_output`; an output that names an input, an HDF5 output named ``.png``, a file output that
        is an existing folder (it had failed only after the work, naming its temporary file).
    """
    figure = getattr(a, "figure", False) and not getattr(a, "out_is_prefix", False)
    out = getattr(a, "out", None)
    if getattr(a, "out_is_prefix", False) and isinstance(out, (str, Path)) and \
            Path(out).suffix.lower() in PREFIX_SUFFIXES:       # a PREFIX named as one of its files: p.csv -> p
        a.out = str(Path(out).with_suffix(""))
    inputs = _input_paths(a)
    for k in OUTPUT_OPTIONS:
        v = getattr(a, k, None)
        if isinstance(v, (str, Path)) and str(v):
            check_output(v)
            o = Path(v)
            if k == "out" and o.is_dir() and not (getattr(a, "out_is_folder", False) or
                                                  getattr(a, "out_is_prefix", False)):
                raise ValueError(f"--out {o} is a folder: name the file to write (in it, or beside it)")
            if figure and o.suffix.lower() == ".png":
                raise ValueError(f"--{k.replace('_', '-')} {o}: name the HDF5 file (e.g. {o.with_suffix('.h5')}); "
                                 "the figure is written beside it as .png")
            if figure and o.with_suffix(".png").is_dir():
                raise ValueError(f"the figure {o.with_suffix('.png')} cannot be written: a folder stands there "
                                 "(--no-figure skips it)")
            for q in inputs:
                if _same(o, q) or (figure and _same(o.with_suffix(".png"), q)):
                    raise ValueError(f"--{k.replace('_', '-')} {o} would overwrite the input {q}: write elsewhere")


def add_search_arg(s):
    """``--search-range``: the depths the search for the planes covers (``--depths auto``)."""
    s.add_argument("--search-range", nargs=2, type=finite, metavar=("NEAR", "FAR"),
                   help="depths (mm from the focus distance, > 0 farther) the search for the planes covers, clipped "
                        "to what the camera can refocus (default: all of that, printed): where the flames are known "
                        "to lie, a narrower search is faster and takes no light outside it for a flame")


def add_camera_args(s):
    """``--camera`` and ``--calibration``: the options of every command that reads a light field."""
    s.add_argument("--camera", help="camera file (TOML: the datasheet tables of docs/own_camera.md, or a [camera] "
                   "table); needed for views from 'lf-flame decode' and for raw captures of a camera that is not "
                   "stored in the file (default: the camera 'lf-flame simulate' stored, else the paper's)")
    s.add_argument("--calibration", help="the white-image calibration JSON of 'lf-flame calibrate': a raw capture is "
                   "decoded with it (its white image) before the route; decoded views are checked against it")


def add_figure_arg(s, what: str) -> None:
    """``--figure/--no-figure`` (``a.figure``, default True) of a command that draws ``what`` beside its output."""
    s.add_argument("--figure", action=argparse.BooleanOptionalAction, default=True,
                   help=f"the figure beside --out (.png: {what}); --no-figure skips it, and with it matplotlib's "
                        "import (about a second of a small camera's command)")


def _level_or_none(text: str):
    """A sensor level for ``--saturation`` (a positive finite number), None for 'none', or 'auto' (found in the
    image); anything else refused (argparse names the option: 'nan' had been taken, every pixel fitted)."""
    t = text.strip().lower()
    if t in ("none", "auto"):
        return None if t == "none" else "auto"
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"takes a positive level, 'auto' or 'none'. Received: {text!r}")
    return v


#: What ``--saturation auto`` does (the help of the commands reading raw images).
AUTO_LEVEL = ("found in the image, where its pixels pile up at its largest value (a sensor clips at one level: a "
              "12-bit sensor's counts in a 16-bit file pile at 4095, or at 65520 shifted to the top bits), else 1.0 "
              "for an image in [0, 1] (integer files are read scaled by their type's range)")
