"""Configuration: frozen dataclasses read from small TOML files, and provenance.

``data_gen/<preset>.toml`` holds the camera and dataset settings, ``experiments/<preset>.toml``
the model and training settings. Every output records the resolved config beside it.
"""
from __future__ import annotations

import contextlib
import dataclasses
import datetime
import json
import numbers
import os
import platform
import subprocess
import tomllib
import zipfile
import zlib
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from .optics.camera import PlenopticCamera
from .simulate.scenes import REGIMES


def split_sizes(n: int, fractions) -> tuple[int, int, int]:
    """The training, validation and test split sizes of ``n`` samples cut by ``fractions``
    (:func:`lf_flame.learn.dataset.split_indices`): the validation split takes at least 1 and leaves the test split 1
    or more; the training split may come out empty, which :class:`DatasetConfig` refuses."""
    n_val = max(1, int(round(fractions[1] * n)))
    n_train = min(int(round(fractions[0] * n)), n - n_val - 1)
    return n_train, n_val, n - n_train - n_val


def _whole(v, least: int = 0) -> bool:
    """Whether ``v`` is a whole number (not a bool) >= ``least``."""
    return isinstance(v, numbers.Integral) and not isinstance(v, bool) and v >= least


@dataclass(frozen=True)
class DatasetConfig:
    """Dataset generation settings.

    Attributes
    ----------
    n_samples : dict scene name -> int
        Samples per scene (paper: 1,600 shapes, 200 flames).
    rays_per_pixel : int
        Monte-Carlo rays per sensor pixel for the training data.
    calibration_rays_per_pixel : int
        Rays per pixel of the nominal scene used by the slope search.
    seed : int
        Base seed; sample ``i`` of scene ``s`` uses ``(seed, s, i)``.
    split : (float, float, float)
        Train/validation/test fractions (paper: 80/10/10).
    regime : str
        Scene regime, one of ``scenes.REGIMES`` (``docs/scenes.md``): ``"paper"`` varies
        only what the paper states (flame heights; shapes with the same ~7 % relative
        spread in size and position), ``"varied"`` also position, size, rotation,
        radiance and flicker (the generalisation test). Default ``"varied"``, the scenes
        of datasets written before regimes existed.
    """

    n_samples: dict
    rays_per_pixel: int = 16
    calibration_rays_per_pixel: int = 64
    seed: int = 2025
    split: tuple = (0.8, 0.1, 0.1)
    regime: str = "varied"

    def __post_init__(self):
        if not (isinstance(self.n_samples, dict)
                and all(isinstance(v, numbers.Integral) for v in self.n_samples.values())):
            raise ValueError("n_samples must be a table of whole numbers per scene (n_samples = { shapes = 1600, "
                             f"flame = 200 }}). Received: {self.n_samples!r}")
        if any(int(v) < 3 for v in self.n_samples.values()):
            raise ValueError(f"each scene needs >= 3 samples for a 3-way split. Received: {self.n_samples}")
        if len(self.split) != 3:
            raise ValueError(f"split takes three fractions (train, validation, test). Received: {self.split}")
        if not all(isinstance(v, numbers.Real) and v > 0 for v in self.split) or abs(sum(self.split) - 1) > 1e-9:
            raise ValueError(f"split fractions must be positive and sum to 1. Received: split={self.split}")   # NaN too
        for scene, n in self.n_samples.items():
            sizes = split_sizes(int(n), self.split)
            if min(sizes) < 1:
                raise ValueError(f"split {list(self.split)} of the {n} {scene} samples leaves an empty split "
                                 f"(train, validation, test: {', '.join(map(str, sizes))}): each needs >= 1 sample; "
                                 "more samples or a larger training fraction")
        if not _whole(self.seed):
            raise ValueError(f"seed must be a whole number >= 0. Received: seed={self.seed!r}")
        if self.regime not in REGIMES:
            raise ValueError(f"regime must be one of {REGIMES}. Received: regime={self.regime!r}")


@dataclass(frozen=True)
class ModelConfig:
    """Model settings: backbone input size (rows, cols), backbone weights, dropout.

    ``weights``: 'imagenet', 'auto' (ImageNet if obtainable, else random init with a
    warning), 'none', or a path to a ``.h5`` weights file. ``dropout_at``: where the
    paper's Dropout(``dropout``) sits, 'gap' (the pooled vector) or 'pixels' (the map
    before the sigmoid convolution); see :data:`lf_flame.learn.model.DROPOUT_PLACES`.
    """

    input_rows: int = 448
    input_cols: int = 224
    weights: str = "auto"
    dropout: float = 0.3
    dropout_at: str = "gap"

    def __post_init__(self):
        if not (isinstance(self.dropout, numbers.Real) and 0 <= self.dropout < 1):         # NaN too
            raise ValueError(f"dropout must be a fraction >= 0 and < 1. Received: dropout={self.dropout!r}")


@dataclass(frozen=True)
class TrainConfig:
    """Training settings (paper: batch 2, Adam 1e-4, MSE; 5,000 / 1,000 epochs).

    ``max_epochs`` and ``time_budget_s`` are per scene; training stops at whichever
    comes first, or when the validation SSIM has not improved for ``patience`` epochs.
    ``recipe``: 'closed-form' (batch-norm statistics of the training split, frozen; the
    Dense layer solved in closed form from the mean image; then the Dense and output
    layers trained at the paper's settings: :func:`lf_flame.learn.closed_form.closed_form_start`) or
    'paper' (every decoder layer trained from a random initialisation with batch
    statistics from batches of 2, as the paper describes; it does not learn here).
    ``refine_iterations`` (per scene): L-BFGS iterations per plane of the closed-form start's
    output-space refinement of the Dense layer (:func:`lf_flame.learn.closed_form.refine_dense`; 0: none).
    ``train_layers``: the decoder layers the 'closed-form' recipe's epochs train, among
    'dense' and 'refocused' (the output 3×3 convolution; :func:`lf_flame.learn.closed_form.freeze_for_probe`).
    """

    recipe: str = "closed-form"
    refine_iterations: dict = dataclasses.field(default_factory=lambda: {"shapes": 40, "flame": 80})
    batch_size: int = 2
    learning_rate: float = 1e-4
    max_epochs: dict = dataclasses.field(default_factory=lambda: {"shapes": 5000, "flame": 1000})
    time_budget_s: dict = dataclasses.field(default_factory=lambda: {"shapes": 3000, "flame": 900})
    patience: int = 20
    seed: int = 7
    train_layers: tuple = ("dense",)

    def __post_init__(self):
        if self.recipe not in ("closed-form", "paper"):
            raise ValueError(f"recipe must be 'closed-form' or 'paper'. Received: recipe={self.recipe!r}")
        for name, least in (("time_budget_s", "> 0"), ("max_epochs", ">= 0 (0: the closed-form start only)")):
            bad = {k: v for k, v in getattr(self, name).items() if not (v > 0 or (v == 0 and name == "max_epochs"))}
            if bad:                                                               # NaN too
                raise ValueError(f"{name} must be {least} for each scene. Received: {name}={bad}")
        if not (self.learning_rate > 0 and self.batch_size >= 1 and self.patience >= 0):
            raise ValueError("learning_rate must be > 0, batch_size >= 1 and patience >= 0. Received: "
                             f"learning_rate={self.learning_rate}, batch_size={self.batch_size}, "
                             f"patience={self.patience}")
        bad = {k: v for k, v in self.refine_iterations.items() if not _whole(v)}
        if bad:
            raise ValueError(f"refine_iterations must be a whole number >= 0 for each scene (0: no refinement). "
                             f"Received: refine_iterations={bad}")
        if not _whole(self.seed):
            raise ValueError(f"seed must be a whole number >= 0. Received: seed={self.seed!r}")
        if not self.train_layers or not set(self.train_layers) <= {"dense", "refocused"}:
            raise ValueError("train_layers must be a non-empty subset of ('dense', 'refocused'). "
                             f"Received: train_layers={self.train_layers!r}")


def _build(cls, d: dict, where: str):
    """``cls(**d)`` from a config table, its refusals as ValueErrors naming ``where`` (a key unknown or missing, a
    value of the wrong type: another kind of config file given, or an edit)."""
    fields = dataclasses.fields(cls)
    names = {f.name for f in fields}
    unknown = set(d) - names
    if unknown:
        raise ValueError(f"{where}: unknown keys {sorted(unknown)} (allowed: {sorted(names)})")
    missing = [f.name for f in fields if f.name not in d and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    if missing:
        raise ValueError(f"{where}: missing {missing} (another kind of config file?)")
    d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
    try:
        return cls(**d)
    except (TypeError, AttributeError) as e:     # a value of the wrong type, met by the checks
        raise ValueError(f"{where}: a value of the wrong type ({e})") from None


def load_toml(path) -> dict:
    """Read a TOML file; a clear error if it is missing or malformed."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file not found: {path}")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"config file {path} is not valid TOML: {e}") from None


def load_data_config(path) -> tuple[PlenopticCamera, DatasetConfig]:
    """Camera and dataset settings from ``data_gen/<preset>.toml``."""
    d = load_toml(path)
    return (_build(PlenopticCamera, d.get("camera", {}), f"{path} [camera]"),
            _build(DatasetConfig, d.get("dataset", {}), f"{path} [dataset]"))


def load_experiment_config(path) -> tuple[ModelConfig, TrainConfig]:
    """Model and training settings from ``experiments/<preset>.toml``."""
    d = load_toml(path)
    return (_build(ModelConfig, d.get("model", {}), f"{path} [model]"),
            _build(TrainConfig, d.get("train", {}), f"{path} [train]"))


def to_json(obj) -> str:
    """JSON of a (nest of) dataclass(es) or dict."""
    if dataclasses.is_dataclass(obj):
        obj = dataclasses.asdict(obj)
    return json.dumps(obj, sort_keys=True, default=str)


def provenance() -> dict:
    """Package versions, machine, threads, the runtime settings that move timings (OpenMP's wait policy,
    :data:`lf_flame.MALLOC_TUNED`), git commit and date, for every result."""
    pkgs = {}
    for name in ("lf_flame", "numpy", "numba", "scipy", "scikit-image", "h5py", "keras", "tensorflow-cpu",
                 "tensorflow", "jax", "pandas", "pylops", "pyproximal"):
        try:
            pkgs[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    import numba

    import lf_flame
    return dict(versions=pkgs, python=platform.python_version(), machine=platform.machine(),
                processor=platform.processor() or platform.machine(), cpu_count=os.cpu_count(),
                numba_threads=numba.get_num_threads(), omp_wait_policy=os.environ.get("OMP_WAIT_POLICY"),
                malloc_tuned=lf_flame.MALLOC_TUNED, git_commit=commit,
                date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))


def atomic_write_text(path, text: str) -> None:
    """Write a text file via a temporary file and rename, so it is never half-written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".partial")
    with removed_on_error(tmp):
        tmp.write_text(text)
        os.replace(tmp, path)


@contextlib.contextmanager
def removed_on_error(tmp):
    """Remove the temporary file ``tmp`` if the block fails (a full disk, Ctrl-C), then re-raise:
    a writer that renames its finished temporary file onto the output leaves nothing half-written.

    Parameters
    ----------
    tmp : path-like
        The temporary file the block writes.
    """
    try:
        yield
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


#: What the file readers raise on an empty, truncated or damaged file: NumPy's .npy (EOFError) and .npz
#: (zipfile's, zlib's), HDF5 (OSError), text (UnicodeDecodeError).
DAMAGED_FILE_ERRORS = (EOFError, zipfile.BadZipFile, zlib.error, OSError, UnicodeDecodeError)


class DamagedFileError(ValueError):
    """An input file that is empty, truncated or damaged (:func:`reading`)."""


@contextlib.contextmanager
def reading(path, what: str = "file"):
    """Read ``path`` inside this block; a damaged file is refused with one message naming it.

    Parameters
    ----------
    path : path-like
        The file being read.
    what : str
        What it should be (``"raw image"``, ``"HDF5 file"``), named in the message.

    Raises
    ------
    DamagedFileError
        A ValueError: the block raised one of :data:`DAMAGED_FILE_ERRORS` (not ``FileNotFoundError``,
        ``PermissionError`` or ``IsADirectoryError``, which pass as they are): ``"PATH is not
        a readable WHAT: the file is empty"``, or ``"...: it is truncated or damaged (REASON)"``.

    Examples
    --------
    >>> with reading("frames.h5", "HDF5 file"):          # doctest: +SKIP
    ...     f = h5py.File("frames.h5", "r")
    """
    try:
        yield
    except (FileNotFoundError, PermissionError, IsADirectoryError):
        raise
    except DAMAGED_FILE_ERRORS as e:
        p = Path(path)
        empty = p.is_file() and p.stat().st_size == 0
        why = "the file is empty" if empty else f"it is truncated or damaged ({e})"
        raise DamagedFileError(f"{p} is not a readable {what}: {why}") from None


def read_json(path, what: str = "JSON file"):
    """The JSON content of ``path``; an empty, truncated or damaged file is refused with one message naming it
    (``json``'s own, "Unterminated string starting at: line 40 column 5 (char 1102)", named no file).

    Raises
    ------
    FileNotFoundError
        No such file (as it is).
    DamagedFileError
        ``"PATH is not a readable WHAT: the file is empty"``, or ``"...: it is truncated or damaged (REASON)"``.
    """
    path = Path(path)
    with reading(path, what):
        text = path.read_text()
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        why = "the file is empty" if not text.strip() else f"it is truncated or damaged ({e})"
        raise DamagedFileError(f"{path} is not a readable {what}: {why}") from None


def stored_json(text, where, record: str):
    """The JSON of a record a file stores (an .npz array's or an HDF5 attribute's text, e.g. ``camera``,
    ``objects``), refused with a message naming the file and the record where it is not JSON (``json``'s own,
    "Expecting property name enclosed in double quotes: line 1 column 2 (char 1)", named neither).

    Parameters
    ----------
    text : str or bytes
        The record as stored.
    where : path-like or str
        The file that stores it (for the message).
    record : str
        The record's name (for the message).

    Raises
    ------
    DamagedFileError
        A ValueError: ``"PATH: its RECORD record is not readable JSON (REASON) ..."``.
    """
    try:
        return json.loads(text.decode() if isinstance(text, bytes) else str(text))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DamagedFileError(f"{where}: its {record!r} record is not readable JSON ({e}): the file is damaged; "
                               f"write it again (or remove the record)") from None
