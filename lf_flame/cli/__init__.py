"""``lf-flame``: the command line that the Make targets call. ``lf-flame --help``.

The argument parser and :func:`main`; the commands, one module per stage, each with its
commands' arguments (``add_parsers``):
:mod:`.optics` (simulate, refocus, slopes), :mod:`.real` (calibrate, decode),
:mod:`.learning` (dataset, train, predict, evaluate, tables), :mod:`.volume` (reconstruct),
:mod:`.resolution` (the camera's depth-resolution map),
:mod:`.temperature_calibration` (calibrate-temperature), :mod:`.temperature` and :mod:`.temperature_recording`
(temperature: two-colour pyrometry of a capture, of a recording; their shared parts in :mod:`.temperature_planes`),
:mod:`.profiles` and :mod:`.sequence` (recordings over time);
:mod:`._io` reads and writes their files and holds the arguments they share.
"""
from __future__ import annotations

import argparse
import gc
import re
import sys
import warnings
from pathlib import Path

from . import learning, optics, profiles, real, resolution, sequence, temperature, temperature_calibration, volume
from .options import check_outputs

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


def build_parser() -> argparse.ArgumentParser:
    """The ``lf-flame`` argument parser: one sub-parser per command, each added by the module that runs it."""
    p = _Parser(prog="lf-flame", description="Light-field refocusing of burner flames: "
                "simulate, refocus, build datasets, train and evaluate the paper's model.")
    sub = p.add_subparsers(dest="command", required=True)
    for stage in (optics, real, volume, profiles, sequence, temperature_calibration, temperature, resolution, learning):
        stage.add_parsers(sub)
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


def _negative_lists(argv: list) -> list:
    """``--depths -39.5,0`` as ``--depths=-39.5,0``: argparse takes a value that starts with '-' and is not one
    number for an option ("expected one argument")."""
    out = []
    for tok in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and re.fullmatch(r"-[\d.]+(,\s*[-+]?[\d.]+)+", tok):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


def main(argv=None) -> int:
    """Run one ``lf-flame`` command and return its exit status (:data:`EXIT_OK` ...).

    The outputs' folders are checked first (:func:`~lf_flame.cli.options.check_outputs`); bad
    input (``ValueError``, :data:`PATH_ERRORS`, a command's ``SystemExit("message")``) gives
    :data:`EXIT_BAD_INPUT`, a failure while running (:data:`RUN_ERRORS`) :data:`EXIT_FAILED`,
    Ctrl-C :data:`EXIT_INTERRUPTED`, each with one line on stderr; the writers leave no
    half-written output (temporary file, then renamed).
    """
    a = build_parser().parse_args(_negative_lists(sys.argv[1:] if argv is None else list(argv)))
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
