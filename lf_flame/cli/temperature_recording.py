"""The ``temperature`` command on a recording: each frame's planes' temperature (the route's operator built
once), on the planes given or found in the first frame, written to HDF5, a CSV of each frame's and plane's
statistics and a figure of each plane's median over time."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..temperature.mosaic import refuse_dead_site, refuse_no_mosaic
from ._io import planes_count, refuse_rgb
from .temperature_planes import (_auto_depths, _level_record, _plane_temperatures, _record, fit_warnings,
                                 given_planes_found)


def recording_source(src):
    """``(source, attrs)`` of the recording at ``src`` (:func:`lf_flame.recordings.sources.open_source`: a folder of
    frames, an HDF5 file holding a ``frames`` stack, a TIFF of more than one page), else None (one capture)."""
    p = Path(src)
    suffix = p.suffix.lower()
    if p.is_file() and suffix == ".h5":
        import h5py

        from ..config import reading
        with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
            if "frames" not in f:
                return None
    elif not (p.is_dir() or (p.is_file() and suffix in (".tif", ".tiff"))):
        return None
    from ..recordings.sources import open_source
    source, attrs = open_source(p)
    return None if suffix in (".tif", ".tiff") and source.n_frames < 2 else (source, attrs)


def temperature_recording(a, source, attrs, cal, sensor, where):
    """``temperature RECORDING``: each frame's planes' temperature (:func:`_plane_temperatures`, the route's operator
    built once), on the planes given or found in the first frame, each frame decoded with ``--grid-calibration``
    where the camera's grid is not a perfect one. Writes ``--out`` (HDF5: ``temperature_k`` and ``valid`` (frame,
    plane, row, col), ``depths_mm``, ``times_s``), its ``.csv`` (per frame and plane: the pixels with a
    temperature, their median, p10 and p90, K) and figure (each plane's median over time); prints each plane's
    dominant frequency of its median temperature (:func:`lf_flame.recordings.flicker.spectra`)."""
    import time

    import h5py
    import pandas as pd
    from tqdm.auto import tqdm

    from ..config import atomic_write_text, provenance, removed_on_error
    from ..optics.camera import PAPER_CAMERA, PlenopticCamera
    from ..real.lightfield import from_raw
    from ..real.readers import decode_capture
    from ..recordings.flicker import peaks, spectra, unresolved_note
    from ..recordings.sources import source_frame_rate
    from .planes import planes_from_args
    src, t0 = str(a.raw), time.perf_counter()
    refuse_rgb(src)
    if "sequence" in attrs and "sensor" not in attrs:
        raise ValueError(f"{src} is a monochrome recording (rendered without a colour sensor): two-colour pyrometry "
                         "needs a colour (Bayer) recording")
    if a.camera:
        from ..optics.camera_file import load_camera_file
        cam, cam_file = load_camera_file(a.camera), str(Path(a.camera).resolve())
    else:
        cam, cam_file = (PlenopticCamera.from_dict(json.loads(attrs["camera"])) if "camera" in attrs
                         else PAPER_CAMERA), None
    grid = images = None
    if a.grid_calibration:
        from ..real.calibration import GridCalibration
        from ..real.images import calibration_image_path, decoding_images
        grid = GridCalibration.load(a.grid_calibration)
        images = decoding_images(calibration_image_path(grid.white, "white"),     # in the frames' units
                                 calibration_image_path(grid.dark, "dark"))
    fps = source_frame_rate(source, attrs, a.fps)
    depths, found, extra, cache, rows, temps, valids, failures = None, None, {}, {}, [], [], [], []
    from ..recordings.sources import tolerant_frames
    for i, raw in enumerate(tqdm(tolerant_frames(source, 0, source.n_frames), total=source.n_frames,
                                 desc="temperature", unit="frame", disable=None)):
        name = f"{src} frame {i}"
        try:
            if isinstance(raw, Exception):                  # a folder's file that cannot be read: that frame fails
                raise raw
            raw = np.asarray(raw, np.float64)
            refuse_dead_site(raw, sensor, name)
            lf = (from_raw(raw, cam, name, camera_file=cam_file, sensor=sensor) if grid is None else
                  decode_capture(raw, cam, grid, sensor, name, images))
            if temps:                                       # the planes are set: a frame that fails is one row
                r = _plane_temperatures(a, lf, depths, found, cal, sensor, cache)
        except ValueError as e:
            if not temps:
                raise ValueError(str(e).replace("--calibration", "--grid-calibration")) from None
            failures.append(f"frame {i}: {e}")                # NaN or inf, no light: no temperature, the rest go on
            temps.append(np.full_like(temps[0], np.nan))
            valids.append(np.zeros_like(valids[0]))
            rows += [dict(frame=i, time_s=i / fps, plane=k, depth_mm=d, n_px=0, median_k=np.nan, p10_k=np.nan,
                          p90_k=np.nan, failure=str(e)) for k, d in enumerate(depths)]
            continue
        if depths is None:                                  # the planes: given, or found in the first frame
            refuse_no_mosaic(raw, name)
            stored = json.loads(attrs["sequence"]).get("flames") if "sequence" in attrs else None  # a simulated one
            depths = planes_from_args(a, lf.camera, stored)
            if depths == "auto":
                depths, found, extra = _auto_depths(a, lf)
            elif a.route != "refocus-cfa":              # planes given: are they where the first frame's flames are?
                given, found = given_planes_found(a, lf, depths)   # near ones held to the regions of their flames
                extra = fit_warnings(a, lf, depths, found=found, given=given)
        if not temps:
            r = _plane_temperatures(a, lf, depths, found, cal, sensor, cache)
        temps.append(r["temp"].astype(np.float32))
        valids.append(r["valid"])
        for k, d in enumerate(depths):
            v = r["temp"][k][r["valid"][k]]
            q = np.percentile(v, [10, 50, 90]) if v.size else (np.nan,) * 3
            rows.append(dict(frame=i, time_s=i / fps, plane=k, depth_mm=d, n_px=int(v.size), median_k=float(q[1]),
                             p10_k=float(q[0]), p90_k=float(q[2]), failure=""))
    if failures:
        print(f"warning: {len(failures)} of {len(temps)} frames have no temperature (the failure column of the CSV): "
              + "; ".join(failures[:3]) + (" ..." if len(failures) > 3 else ""), file=sys.stderr)
    df = pd.DataFrame(rows)
    wall = time.perf_counter() - t0
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f["temperature_k"] = np.stack(temps)
        f["temperature_k"].attrs.update(units="K", masked="NaN: no temperature (see valid)")
        f["valid"] = np.stack(valids)
        f["depths_mm"] = np.asarray(depths, float)
        f["times_s"] = np.arange(len(temps)) / fps
        attrs_out = dict(kind="lf_flame temperature recording", source=src, fps=float(fps),
                         **_record(a, cal, sensor, where, r["chosen"]), saturation=_level_record(a.saturation, lf),
                         camera=lf.camera.to_json(), time_s=wall,
                         provenance=json.dumps(provenance()),
                         axes="temperature_k, valid: (frame, plane, lenslet row, lenslet col)",
                         **{k: json.dumps(v, default=float) for k, v in extra.items()})
        for k, v in attrs_out.items():
            f.attrs[k] = v
    tmp.replace(out)
    atomic_write_text(out.with_suffix(".csv"), df.to_csv(index=False))
    fig = out.with_suffix(".png") if a.figure else None
    if fig is not None:
        from ..measure.figures import save_figure
        save_figure(recording_figure(df), fig)
    if len(temps) > 1:
        pk = peaks(spectra(df, fps, signals=("median_k",)))
        print(pk[["plane", "depth_mm", "bin_hz", "dominant_hz", "amplitude", "resolved"]].to_string(
            index=False, float_format=lambda v: f"{v:.3g}"))
        note = unresolved_note(pk)
        if note:
            print(note)
    med = df.groupby("plane").median_k
    for k, d in enumerate(depths):
        print(f"plane {k} ({d:+.2f} mm): median temperature over the frames {med.median()[k]:.0f} K "
              f"(frames' medians {med.min()[k]:.0f}-{med.max()[k]:.0f} K)")
    print(f"temperature of {planes_count(len(depths))} in {len(temps)} frames ({a.route}) in {wall:.1f} s "
          f"({len(temps) / wall:.2f} frames/s) -> {out}, {out.with_suffix('.csv')}" + (f", {fig}" if fig else ""))


def recording_figure(df):
    """Each plane's median temperature over a recording's frames, its p10-p90 band shaded."""
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for (k, d), g in df.groupby(["plane", "depth_mm"], sort=True):
        line, = ax.plot(g.time_s, g.median_k, label=f"plane {k} ({d:+.1f} mm)")
        ax.fill_between(g.time_s, g.p10_k, g.p90_k, color=line.get_color(), alpha=0.2)
    ax.set(xlabel="time (s)", ylabel="temperature (K): median, p10-p90")
    ax.legend(fontsize="small")
    fig.tight_layout()
    return fig
