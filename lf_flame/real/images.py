"""Real cameras: reading and checking the images a calibration and a decoding take (white, dark
and raw images), and the white or dark image a calibration names, checked by its SHA-256.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np


def load_image(path) -> np.ndarray:
    """Read a white, dark or raw image: .npy, .npz (key ``raw``, else its only array), or any
    image file scikit-image reads (PNG, TIFF; 8 or 16 bit). Colour is averaged to gray.

    Returns
    -------
    image : ndarray of shape (rows, cols), float64 (the file's values, unscaled)
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"image file not found: {p}")
    from ..config import reading
    if p.suffix == ".npy":
        with reading(p, ".npy file"):
            a = np.load(p)
    elif p.suffix == ".npz":
        with reading(p, ".npz file"), np.load(p) as z:
            keys = list(z.keys())
            if "raw" in keys:
                a = z["raw"]
            elif len(keys) == 1:
                a = z[keys[0]]
            else:
                raise ValueError(f"{p}: .npz with keys {keys}; expected 'raw' or a single array")
    else:
        from skimage import io
        try:
            a = io.imread(p)
        except Exception as e:  # the readers raise many kinds
            raise ValueError(f"{p} is not a readable image: {e}") from None
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[-1] in (3, 4):
        a = a[..., :3].mean(axis=-1)
    return a.astype(np.float64)


def file_digest(path) -> dict:
    """``{"path": absolute path, "sha256": hex digest}`` of a file."""
    p = Path(path).resolve()
    return {"path": str(p), "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}


def _image(name, a, shape=None) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 2 or min(a.shape) < 1:
        raise ValueError(f"{name} must be a 2-D image (rows, columns). Received shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise ValueError(f"{name} must be real-valued. Received dtype {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf ({int(np.sum(~np.isfinite(a)))} pixels)")
    if shape is not None and a.shape != tuple(shape):
        raise ValueError(f"{name} has shape {a.shape}, not the {tuple(shape)} of the calibration's sensor")
    return a


def _dark_subtracted(name, image, dark):
    img = _image(name, image)
    if dark is not None:
        img = img - _image("dark frame", dark, img.shape)
    return img


def calibration_image(info, kind: str, override=None):
    """The white or dark image a calibration names (``GridCalibration.white``/``.dark``), checked
    against its SHA-256; ``override``: a path read instead, unchecked. None when neither is given.

    Raises
    ------
    FileNotFoundError
        The named image is gone (give it again as ``--white``/``--dark``).
    ValueError
        The named image has changed since the calibration.
    """
    if override:
        return load_image(override)
    if not info:
        return None
    p = Path(info["path"])
    if not p.is_file():
        raise FileNotFoundError(f"the calibration's {kind} image {p} is gone; give it with --{kind}")
    if file_digest(p)["sha256"] != info["sha256"]:
        raise ValueError(f"the calibration's {kind} image {p} has changed since the calibration")
    return load_image(p)
