"""The files of the command line (:mod:`lf_flame.cli`): raw images, views, stacks and the
objects stored beside a simulated raw image. Serves every command group.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def _load_raw(path):
    """A raw image from .npz (key 'raw'), .npy, or a dataset sample 'file.h5:INDEX'."""
    s = str(path)
    if ".h5:" in s:
        from ..learn.dataset import LightFieldDataset
        f, i = s.rsplit(":", 1)
        ds = LightFieldDataset(f)
        return ds.raw(int(i)), ds.camera
    p = Path(s)
    if not p.is_file():
        raise SystemExit(f"error: raw image file not found: {p}")
    if p.suffix == ".npz":
        with np.load(p) as z:
            from ..optics.camera import PlenopticCamera
            cam = PlenopticCamera.from_dict(json.loads(str(z["camera"]))) if "camera" in z else None
            return z["raw"], cam
    return np.load(p), None


def _load_views(path):
    """Sub-aperture views (N, N, R, C) and the camera (or None) of RAW: a file of views
    decoded by ``lf-flame decode`` (.h5 without ':INDEX'), else a raw image of the
    simulated camera split by :func:`lf_flame.refocus.shift_and_sum.raw_to_views`."""
    s = str(path)
    if s.endswith(".h5") and ".h5:" not in s:
        from ..real.decoding import load_views
        return load_views(s)[0], None
    from ..optics.camera import PAPER_CAMERA
    from ..refocus.shift_and_sum import raw_to_views
    raw, cam = _load_raw(path)
    cam = cam or PAPER_CAMERA
    return raw_to_views(raw, cam.pixels_per_lenslet), cam


def _save_image(path, img):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.imsave(path, np.clip(img, 0, 1), cmap="gray", vmin=0, vmax=1)


def _write_stack(path, stack, **extra):
    """Write a focal stack (S, R, C): planes side by side as .png, else .npz with ``extra``."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".png":
        _save_image(out, np.concatenate(list(stack), axis=1))
    else:
        np.savez_compressed(out, stack=stack, **extra)
    print(f"-> {out}")


def _raw_objects(path):
    """The objects (with ``roi``) that ``lf-flame simulate`` stored beside the raw image, if any."""
    if not str(path).endswith(".npz"):
        return None
    with np.load(path) as z:
        return json.loads(str(z["objects"])) if "objects" in z else None
