"""Real cameras, decoding's output: the HDF5 file of decoded views that ``lf-flame decode`` writes.

:func:`save_views` writes the views of :mod:`lf_flame.real.decoding` (with their calibration,
the samples from clipped pixels and, for a colour capture, each sample's channel) atomically;
:func:`load_views`, :func:`load_clipped`, :func:`load_channels` and :func:`load_lattice` read them back.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .calibration import GridCalibration


def save_views(path, views: np.ndarray, calibration: GridCalibration, clipped: np.ndarray | None = None,
               channels: np.ndarray | None = None, lattice_views: np.ndarray | None = None,
               lattice_clipped: np.ndarray | None = None, **attrs) -> Path:
    """Write decoded views to HDF5 (dataset ``views``, (N, N, R, C) float32; the calibration
    as JSON in attribute ``calibration``), atomically: a temporary file, then renamed.
    ``clipped`` (bool, the views' shape; :func:`clipped_samples`) goes in dataset ``clipped``,
    a colour capture's ``channels`` (int8, :func:`decode_colour`; the views' shape, a hexagonal
    grid's: the lattice views', which its channels stay on) in dataset ``channels``; a hexagonal
    grid's views on its own lattice (``decode(..., resample=False)``, (N, N, rows, lenslets per
    row)) and their clipped samples in ``lattice_views`` and ``lattice_clipped``."""
    import os

    import h5py
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".partial")
    from ..config import removed_on_error
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f.create_dataset("views", data=np.asarray(views, np.float32), compression="gzip", compression_opts=1)
        if clipped is not None:
            if np.shape(clipped) != np.shape(views) or np.asarray(clipped).dtype != bool:
                raise ValueError(f"clipped must be boolean of the views' shape {np.shape(views)}. Received: "
                                 f"{np.asarray(clipped).dtype} of shape {np.shape(clipped)}")
            f.create_dataset("clipped", data=np.asarray(clipped), compression="gzip", compression_opts=1)
        if channels is not None:
            mapped = np.shape(views) if lattice_views is None else np.shape(lattice_views)
            if np.shape(channels) != mapped:
                raise ValueError(f"channels must have the shape {mapped} of the views they map. Received: "
                                 f"{np.shape(channels)}")
            f.create_dataset("channels", data=np.asarray(channels, np.int8), compression="gzip", compression_opts=1)
        if lattice_views is not None:
            if np.ndim(lattice_views) != 4 or np.shape(lattice_views)[:2] != np.shape(views)[:2]:
                raise ValueError(f"lattice views must be (N, N, rows, cols) with the views' N. Received: shape "
                                 f"{np.shape(lattice_views)}")
            f.create_dataset("lattice_views", data=np.asarray(lattice_views, np.float32), compression="gzip",
                             compression_opts=1)
            if lattice_clipped is not None:
                if np.shape(lattice_clipped) != np.shape(lattice_views):
                    raise ValueError("lattice_clipped must have the lattice views' shape")
                f.create_dataset("lattice_clipped", data=np.asarray(lattice_clipped, bool), compression="gzip",
                                 compression_opts=1)
        f.attrs["format"] = "lf_flame.decoded_views"
        f.attrs["calibration"] = json.dumps(calibration.to_dict())
        for k, v in attrs.items():
            f.attrs[k] = v
    os.replace(tmp, p)
    return p


def load_views(path) -> tuple[np.ndarray, GridCalibration]:
    """Read :func:`save_views`' file: views (N, N, R, C) float32 and the calibration.

    Raises
    ------
    ValueError
        Not a file of decoded views; one without its calibration, or with one that cannot be read (each named
        with the file).
    """
    import h5py
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"views file not found: {p}")
    from ..config import reading
    with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
        if f.attrs.get("format") != "lf_flame.decoded_views" or "views" not in f:
            raise ValueError(f"{p} is not a file of decoded views written by 'lf-flame decode'")
        views = f["views"][...]
        if "calibration" not in f.attrs:
            raise ValueError(f"{p} lacks its lenslet grid's calibration (attribute 'calibration', which "
                             "'lf-flame decode' writes): decode the capture again")
        from ..config import stored_json
        record = stored_json(f.attrs["calibration"], p, "calibration")
        try:
            cal = GridCalibration.from_dict(record)
        except ValueError as e:
            raise ValueError(f"{p}: its 'calibration' attribute is not a lenslet grid's calibration ({e}): decode "
                             "the capture again") from None
    if views.ndim != 4 or views.shape[0] != views.shape[1]:
        raise ValueError(f"{p}: views of shape {views.shape}, not (N, N, R, C)")
    return views, cal


def load_channels(path) -> np.ndarray | None:
    """The channel map (int8, (N, N, R, C); 0 R, 1 G, 2 B) of :func:`save_views`' file of a colour
    capture (:func:`decode_colour`; of its lattice views for a hexagonal grid), or None for a
    monochrome one."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        return f["channels"][...].astype(np.int8) if "channels" in f else None


def load_clipped(path) -> np.ndarray | None:
    """The ``clipped`` mask (bool, (N, N, R, C)) of :func:`save_views`' file, or None when it
    has none (decoded without a saturation level, or before decoding recorded one)."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        return f["clipped"][...].astype(bool) if "clipped" in f else None


def load_lattice(path) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A hexagonal grid's views on its own lattice and their clipped samples from :func:`save_views`'
    file: ``(views, clipped)``, float32 and bool of shape (N, N, rows, lenslets per row); ``(None,
    None)`` where the file has none (a square grid, or decoded before they were kept), the clipped
    samples None where it has no mask."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        if "lattice_views" not in f:
            return None, None
        return (f["lattice_views"][...].astype(np.float32),
                f["lattice_clipped"][...].astype(bool) if "lattice_clipped" in f else None)
