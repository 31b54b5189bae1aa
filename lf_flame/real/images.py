"""Real cameras: reading and checking the images a calibration and a decoding take (white, dark
and raw images), and the white or dark image a calibration names, checked by its SHA-256.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from .clipping import clipping_pile


def load_image(path) -> np.ndarray:
    """Read a white, dark or raw image: .npy, .npz (key ``raw``, else its only array), or any
    image file scikit-image reads (PNG, TIFF; 8 or 16 bit). Colour is averaged to gray
    (:func:`to_gray`, its clipped pixels kept clipped).

    Returns
    -------
    image : ndarray of shape (rows, cols), float64 (the file's values, unscaled)
    """
    return to_gray(read_image(path)).astype(np.float64)


def read_image(path) -> np.ndarray:
    """The array an image file holds, in its own dtype (as :func:`load_image` reads it, before the gray mean and
    float64): a recording's frames scale it by its type's range (:func:`frame_image`).

    Raises
    ------
    FileNotFoundError, ValueError
        No such file; an unreadable file, an .npz of several arrays none of which is ``raw``.
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
    return a


def frame_units(a: np.ndarray) -> np.ndarray:
    """A recording's frame (or an image read as one) as float32 (H, W): integers scaled by their type's range, colour
    averaged to gray (:func:`to_gray`, its clipped pixels kept clipped)."""
    a = np.asarray(a)
    scale = 1.0 / np.iinfo(a.dtype).max if np.issubdtype(a.dtype, np.integer) else 1.0
    return np.asarray(to_gray(a), np.float32) * np.float32(scale)


def frame_image(path) -> np.ndarray:
    """An image file (:func:`read_image`: .npy, .npz, PNG, TIFF) in a recording's frames' units (:func:`frame_units`).
    A recording's white image and dark frame are read so, as its frames are: decoding divides by the white image,
    whose units must be the frames' (a 12-bit TIFF's counts against PNG frames scaled to [0, 1] left every sample
    1/4095 of its light)."""
    return frame_units(read_image(path))


def decoding_images(white, dark) -> tuple:
    """A recording's white image and dark frame (paths or None) read in its frames' units (:func:`frame_image`), as
    :func:`lf_flame.real.readers.decode_capture` takes them: (white, dark), each (H, W) float64 or None."""
    return tuple(None if p is None else frame_image(p).astype(np.float64) for p in (white, dark))


def to_gray(a: np.ndarray) -> np.ndarray:
    """An image as one gray channel: a colour image (rows, cols, 3 or 4; alpha dropped) averaged over its
    channels, its clipped pixels kept clipped; a gray image as it is.

    A colour camera's channels clip apart (a flame's red first), and their mean no longer piles up
    at one value: a pixel whose channel sits at that channel's clipping level
    (:func:`lf_flame.real.clipping.clipping_pile`) is given the largest of the channels' levels, so
    that the gray image piles up there and the level is found in it
    (:func:`lf_flame.real.clipping.auto_saturation`).

    Parameters
    ----------
    a : ndarray of shape (rows, cols) or (rows, cols, 3 | 4)

    Returns
    -------
    ndarray of shape (rows, cols)
        float64 for a colour image (the channels' units), else ``a`` as it is.
    """
    a = np.asarray(a)
    if not (a.ndim == 3 and a.shape[-1] in (3, 4)):
        return a
    rgb = a[..., :3]
    gray = rgb.mean(axis=-1, dtype=np.float64)
    piles = {c: p for c in range(3) if (p := clipping_pile(rgb[..., c])) is not None}
    if piles:
        gray[np.any([rgb[..., c] >= p for c, p in piles.items()], axis=0)] = max(piles.values())
    return gray


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
    p = calibration_image_path(info, kind, override)
    return None if p is None else load_image(p)


def calibration_image_path(info, kind: str, override=None):
    """The path of the white or dark image a calibration names, checked as :func:`calibration_image` checks it
    (``override`` unchecked); None when neither is given. Raises as :func:`calibration_image`."""
    if override:
        return str(override)
    if not info:
        return None
    p = Path(info["path"])
    if not p.is_file():
        raise FileNotFoundError(f"the calibration's {kind} image {p} is gone; give it with --{kind}")
    if file_digest(p)["sha256"] != info["sha256"]:
        raise ValueError(f"the calibration's {kind} image {p} has changed since the calibration")
    return str(p)
