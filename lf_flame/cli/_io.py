"""The files of the command line (:mod:`lf_flame.cli`): raw images, views, stacks and the
objects stored beside a simulated raw image. Serves every command group.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np


#: What the commands read as a raw image (``--help`` and the refusals name it).
RAW_FORMATS = (".npz from 'lf-flame simulate' (key 'raw'), .npy, a PNG or TIFF image (integers scaled to [0, 1]; "
               "'simulate --out RAW.png' stores its camera and objects in the PNG, other images and .npy get the "
               "paper's camera), DATASET.h5:INDEX, or RECORDING.h5:INDEX (one frame of a recording)")
#: What ``simulate`` stores beside the raw image (JSON strings): arrays of its .npz, text of its PNG (``lf_flame.KEY``);
#: ``sensor`` (a colour image's sensitivities' name, CFA pattern and phase) is read by the temperature commands.
META_KEYS = ("camera", "objects", "scene", "sensor")
#: Image files read as a raw image (scikit-image).
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")
#: Layers of the volume scene of 'lf-flame simulate --scene volume' (as experiments/volume.py's volumes); its
#: diameter is 10 mm, at most 85 % of the field's width at its depth.
VOLUME_LAYERS = 32


def _read_image(p: Path) -> np.ndarray:
    """A PNG/TIFF raw image as float64 (rows, cols): integers scaled to [0, 1] by their type's
    range (what ``simulate --out RAW.png`` wrote reads back as the clipped raw image,
    quantised to 8 bits), colour averaged to gray (:func:`lf_flame.real.images.to_gray`)."""
    from skimage import io, util
    try:
        a = io.imread(p)
    except Exception as e:  # the image readers raise many kinds
        raise ValueError(f"{p} is not a readable image: {e}") from None
    from ..real.images import to_gray
    return to_gray(util.img_as_float64(a))


def refuse_rgb(path) -> None:
    """Refuse an image (or a folder's first image, a multi-page TIFF's pages) of three or four colour channels where
    a colour filter array's raw mosaic is needed (temperature, its calibration, a colour capture's decoding): read as
    one, a demosaiced RGB image is averaged to gray and its 2 x 2 phases taken for the CFA's, which gave
    temperatures 600-750 K too hot without a word.

    Raises
    ------
    ValueError
        Naming the file and its shape.
    """
    p = Path(re.sub(r":\d+$", "", str(path)))
    files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)[:1] if p.is_dir() else \
        [p] if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file() else []
    from skimage import io
    for f in files:
        try:
            shape = io.imread(f).shape
        except Exception:      # the image readers raise many kinds; the reader proper names the damage
            continue
        if len(shape) >= 3 and shape[-1] in (3, 4) and min(shape[-3:-1]) > 4:
            raise ValueError(f"{f} holds {shape[-1]} colour channels per pixel (shape {shape}): a demosaiced RGB "
                             "image, not the sensor's raw mosaic. Two-colour pyrometry needs the raw colour filter "
                             "array image (each pixel one channel): save the camera's raw (Bayer) frames")


def _recording_frame(path, index):
    """Frame ``index`` of a recording's HDF5 stack (its dataset ``frames``: ``lf-flame simulate-sequence``'s, a
    camera's), in its frames' units (:class:`~lf_flame.recordings.sources.H5Source`), and the camera it records
    (or None); None where the file holds no ``frames`` (a dataset of light fields).

    Raises
    ------
    ValueError
        An index that is not a whole number within the recording's frames.
    """
    import h5py
    p = Path(path)
    if not p.is_file():
        return None
    from ..config import reading
    with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
        if "frames" not in f or f["frames"].ndim != 3:
            return None
        n, cam_json = int(f["frames"].shape[0]), f.attrs.get("camera")
    if not (str(index).strip().isdigit() and int(index) < n):
        raise ValueError(f"{p}:{index}: a recording of {n} frames takes a frame index 0 .. {n - 1}")
    from ..recordings.sources import H5Source
    cam = None
    if cam_json is not None:
        from ..optics.camera import PlenopticCamera
        from ..config import stored_json
        cam = PlenopticCamera.from_dict(stored_json(cam_json, p, "camera"))
    return H5Source(str(p)).raw(int(index)), cam


def _load_raw(path):
    """A raw image (rows, cols) and its camera (or None): see :data:`RAW_FORMATS`.

    Raises
    ------
    ValueError
        A file of another kind (the message names the formats read), not a 2-D image, or an
        empty, truncated or damaged file (:func:`lf_flame.config.reading`).
    FileNotFoundError
        The file does not exist.
    """
    from ..config import reading
    s = str(path)
    if ".h5:" in s:
        f, i = s.rsplit(":", 1)
        frame = _recording_frame(f, i)
        if frame is not None:
            return frame
        from ..learn.dataset import LightFieldDataset
        with reading(f, "dataset (HDF5)"):
            ds = LightFieldDataset(f)
            if not (i.strip().isdigit() and int(i) < ds.n):
                raise ValueError(f"{s}: a dataset of {ds.n} samples takes a sample index 0 .. {ds.n - 1}")
            return ds.raw(int(i)), ds.camera
    p = Path(s)
    if not p.is_file():
        raise FileNotFoundError(f"raw image file not found: {p}")
    suffix = p.suffix.lower()
    if suffix == ".npz":
        with reading(p, ".npz file"), np.load(p) as z:
            if "raw" not in z:
                raise ValueError(f"{p} holds no raw image (its arrays: {', '.join(z.files)}). A raw image is "
                                 + RAW_FORMATS)
            raw = z["raw"]
    elif suffix == ".npy":
        with reading(p, ".npy file"):
            try:
                raw = np.load(p)
            except ValueError:   # NumPy's message speaks of pickles (or of a reshape): not the user's problem
                raise ValueError(f"{p} is not a NumPy array file (or it is truncated). A raw image is "
                                 + RAW_FORMATS) from None
    elif suffix in IMAGE_SUFFIXES:
        raw = _read_image(p)
    else:
        raise ValueError(f"cannot read {p} as a raw image ({suffix or 'no suffix'}). A raw image is " + RAW_FORMATS)
    if raw.ndim != 2:
        raise ValueError(f"{p}: an array of shape {raw.shape} is not a raw image (rows, cols)")
    meta = _raw_meta(p)
    cam = None
    if "camera" in meta:
        from ..optics.camera import PlenopticCamera
        from ..config import stored_json
        cam = PlenopticCamera.from_dict(stored_json(meta["camera"], p, "camera"))
    return raw, cam


def _raw_meta(path) -> dict:
    """What ``simulate`` stored beside a raw image (:data:`META_KEYS` -> JSON string): the
    arrays of its .npz or the text of its PNG; for a frame of a recording (``RECORDING.h5:INDEX``) the
    recording's camera, sensor and sequence (``simulate-sequence``'s attributes); empty for any other file."""
    from ..config import reading
    if ".h5:" in str(path):
        import h5py
        f = Path(str(path).rsplit(":", 1)[0])
        if not f.is_file():
            return {}
        with reading(f, "HDF5 file"), h5py.File(f, "r") as h:
            if "frames" not in h:                       # a dataset of light fields
                return {}
            return {k: str(h.attrs[k]) for k in ("camera", "sensor", "sequence") if k in h.attrs}
    p = Path(str(path))
    suffix = p.suffix.lower()
    if suffix == ".npz" and p.is_file():
        with reading(p, ".npz file"), np.load(p) as z:
            return {k: str(z[k]) for k in META_KEYS if k in z}
    if suffix == ".png" and p.is_file():
        from PIL import Image
        with reading(p, "PNG image"), Image.open(p) as im:     # PIL's UnidentifiedImageError is an OSError
            text = dict(getattr(im, "text", {}))
        return {k: text[f"lf_flame.{k}"] for k in META_KEYS if f"lf_flame.{k}" in text}
    return {}


def _raw_reader(p):
    raw, cam = _load_raw(p)
    return raw, cam, _raw_meta(p)


def light_field(a, path=None, colour: bool = False):
    """The light field of a command's input (``a.raw`` or ``path``) with its ``--camera`` and
    ``--calibration`` (:func:`lf_flame.real.readers.read_light_field`); a colour capture's
    decoded views as one monochrome light field
    (:func:`lf_flame.temperature.mosaic.monochrome_light_field`) unless ``colour``."""
    from ..real.readers import read_light_field
    lf = read_light_field(path or a.raw, getattr(a, "camera", None), getattr(a, "calibration", None),
                          views=getattr(a, "views", None), raw_reader=_raw_reader, formats=RAW_FORMATS)
    black_level_warning(lf.unlit_level)
    if lf.channels is None or colour:
        return lf
    from ..temperature.mosaic import monochrome_light_field
    return monochrome_light_field(lf)


def black_level_warning(unlit: float | None) -> None:
    """Where a decoded capture's unlit pixels read more than :data:`~lf_flame.real.black_level.BLACK_LEVEL_SHARE`
    of its bright ones (``unlit``: :func:`lf_flame.real.black_level.unlit_level`), one warning (stderr): a black
    level or stray light left in, and how to subtract it."""
    from ..real.black_level import BLACK_LEVEL_SHARE
    if unlit is not None and unlit > BLACK_LEVEL_SHARE:
        print(f"warning: the capture's pixels that no light reaches (where the white image is dark, between the "
              f"lenslet images) read {100 * unlit:.3g} % of its bright pixels: a black level (the sensor's offset) "
              "or stray light left in, which no plane of emission explains and which bends the dim samples' "
              "division by the white image; calibrate with the dark frame (lf-flame calibrate --dark) or decode "
              "with it (--dark)", file=sys.stderr)


def _save_image(path, img, metadata=None, bits: int = 8):
    """An image in [0, 1] as a gray PNG of ``bits`` (8 or 16) bits: clipped, rounded to the
    nearest level; ``metadata`` (str -> str) goes in its text chunks. Written to a temporary
    file, then renamed."""
    from PIL import Image, PngImagePlugin
    top = (1 << bits) - 1
    q = np.round(np.clip(np.asarray(img, np.float64), 0, 1) * top).astype(np.uint16 if bits > 8 else np.uint8)
    info = PngImagePlugin.PngInfo()
    for k, v in (metadata or {}).items():
        info.add_text(k, v)
    path = Path(path)
    _written(path, path.with_name(path.name + ".partial"), lambda t: Image.fromarray(q).save(t, format="PNG",
                                                                                              pnginfo=info))


def save_npz(path, **arrays) -> Path:
    """``arrays`` in a compressed .npz at ``path`` (".npz" added where it lacks it, as NumPy adds it), written to a
    temporary file, then renamed; returns the path written (the one to print: 'simulate --out p.txt' had printed
    p.txt for p.txt.npz)."""
    out = Path(path)
    if out.suffix != ".npz":
        out = out.with_name(out.name + ".npz")
    _written(out, out.with_name(out.name + ".partial.npz"), lambda t: np.savez_compressed(t, **arrays))
    return out


def _written(path: Path, tmp: Path, write) -> None:
    """``write(tmp)``, then ``tmp`` renamed onto ``path``; ``tmp`` removed if either fails (nothing half-written)."""
    import os
    from ..config import removed_on_error
    with removed_on_error(tmp):
        write(tmp)
        os.replace(tmp, path)


def _write_stack(path, stack, **extra):
    """Write a focal stack (S, R, C): planes side by side as .png, else .npz with ``extra``."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".png":
        _save_image(out, np.concatenate(list(stack), axis=1))
    else:
        out = save_npz(out, stack=stack, **extra)
    print(f"-> {out}")


def planes_count(n: int) -> str:
    """``"1 plane"``, ``"4 planes"``: the commands' counts of planes in words."""
    return f"{n} plane{'s' * (n != 1)}"


def _raw_objects(path):
    """The objects (with ``roi``) that ``lf-flame simulate`` stored beside the raw image, if any."""
    meta = _raw_meta(path)
    from ..config import stored_json
    return stored_json(meta["objects"], path, "objects") if "objects" in meta else None


def _recording_flames(path):
    """The flames (``depth_offset_mm``, ``height_mm`` ...; no ``roi``) of the simulated recording that a frame
    ``RECORDING.h5:INDEX`` comes from (``simulate-sequence``'s ``sequence``), or None."""
    meta = _raw_meta(path) if ".h5:" in str(path) else {}
    from ..config import stored_json
    return stored_json(meta["sequence"], path, "sequence").get("flames") if "sequence" in meta else None


#: ``lf-flame simulate``'s scenes seen by a colour (Bayer) sensor (:func:`colour_scene`).
COLOUR_SCENES = ("colour-flame", "colour-depth", "furnace")


def render_sensor(named, camera_file):
    """The colour sensor a colour render goes through and where it came from: ``named`` (the camera file's
    ``[sensor] cfa``), else the default sensitivities with an RGGB mosaic."""
    if named is not None:
        return named, f"{camera_file} [sensor]"
    from ..optics.colour import DEFAULT_SENSITIVITIES, library_sensor
    return library_sensor(DEFAULT_SENSITIVITIES, "RGGB", (0, 0)), "default: the camera file names no cfa"


def colour_scene(record: dict, camera):
    """A colour scene of ``lf-flame simulate`` from its record: ``(scene, channel_radiance, sensor)`` for
    :func:`lf_flame.simulate.colour.render_colour`.

    The record holds ``kind`` (one of :data:`COLOUR_SCENES`), ``seed``, ``nominal``, ``sensor`` (``name``,
    ``pattern``, ``phase``) and for a furnace ``temperature_k``. ``colour-flame``: the paper's four flames
    with their temperature fields (:func:`lf_flame.simulate.scenes_temperature.colour_flame_scene`);
    ``colour-depth``: 2-4 flames at random depths scaled to the camera, each with a drawn sheath temperature
    (:func:`~lf_flame.simulate.scenes_temperature.colour_depth_scene`); ``furnace``: a blackbody filling the
    field (:func:`~lf_flame.simulate.scenes_temperature.furnace_scene`), the flat field that
    ``lf-flame calibrate-temperature`` takes; ``white`` (a camera file naming its CFA): the white target
    through the mosaic (:func:`~lf_flame.simulate.scenes_temperature.white_target_scene`).
    """
    from ..optics.colour import library_sensor
    from ..simulate import scenes_temperature as st
    from ..simulate.scenes_depth import paper_layout
    sr = record["sensor"]
    sensor = library_sensor(sr["name"], sr["pattern"], tuple(sr["phase"]))
    rng = np.random.default_rng(record["seed"])
    if record["kind"] == "furnace":
        scene, chans = st.furnace_scene(camera, sensor, record["temperature_k"])
        return scene, chans, sensor
    if record["kind"] == "white":
        scene, chans = st.white_target_scene(camera, sensor)
        return scene, chans, sensor
    cs = (st.colour_flame_scene(camera, sensor, None if record["nominal"] else rng, **paper_layout(camera))
          if record["kind"] == "colour-flame" else st.colour_depth_scene(camera, sensor, rng))
    return cs.scene, list(cs.channel_radiance), sensor


def simulated_scene(record: dict, camera):
    """The scene of ``lf-flame simulate`` from its record (``kind``, ``seed``, ``nominal``; a
    point: ``depth_mm``, ``y_mm``, ``x_mm``; a volume: ``depth_mm`` and ``x_mm``, its axis's depth and lateral
    place (drawn whole where it reaches past the field's edge); ``depth``:
    :func:`lf_flame.simulate.scenes_depth.camera_depth_scene`; ``white``: a flat field; a colour
    scene: :func:`colour_scene`'s, its layers' radiance the green channel's), the one it renders and
    stores beside the raw image."""
    from ..simulate import scenes
    if record["kind"] in COLOUR_SCENES:
        return colour_scene(record, camera)[0]
    if record["kind"] == "point":
        return scenes.point_scene(camera, record["depth_mm"], record["y_mm"], record["x_mm"])
    if record["kind"] == "white":
        return scenes.white_scene(camera)
    if record["kind"] == "depth":
        from ..simulate.scenes_depth import camera_depth_scene
        return camera_depth_scene(camera, np.random.default_rng(record["seed"]))
    if record["kind"] == "volume":
        from ..simulate.scenes_volume import volume_flame_scene
        dz, x = record.get("depth_mm") or 0.0, record.get("x_mm") or 0.0
        diameter = min(10.0, 0.85 * camera.field_of_view_mm(dz)[1])
        narrowest = camera.field_of_view_mm(dz - diameter / 2)[1]          # the nearest layer's field
        return volume_flame_scene(camera, None if record["nominal"] else np.random.default_rng(record["seed"]),
                                  centre_depth_mm=dz, n_layers=VOLUME_LAYERS, diameter_mm=diameter, centre_x_mm=x,
                                  field_margin=max(1.2, 2 * (abs(x) + 0.9 * diameter) / narrowest))
    from ..simulate.scenes_depth import paper_layout
    layout = paper_layout(camera)
    if record["kind"] == "shapes":
        layout.pop("template_scale")
    return scenes.SCENES[record["kind"]](camera, np.random.default_rng(record["seed"]), vary=not record["nominal"],
                                         **layout)


def _raw_scene(path, camera):
    """The scene ``lf-flame simulate`` rendered into RAW (an .npz), rebuilt from its record,
    or None: no record (another file, an older one), or a rebuilt scene whose objects are
    not the stored ones (the scenes have changed since)."""
    meta = _raw_meta(path)
    if "scene" not in meta or "objects" not in meta:
        return None
    from ..config import stored_json
    record, objects = stored_json(meta["scene"], path, "scene"), stored_json(meta["objects"], path, "objects")
    sc = simulated_scene(record, camera)
    return sc if json.loads(json.dumps(sc.objects, default=float)) == objects else None


def camera_config(path):
    """The camera of a TOML file: the datasheet tables of a camera file
    (:func:`lf_flame.optics.camera_file.load_camera_file`), or a ``[camera]`` table (the
    paper's values for the keys it leaves out; a data config without one: the paper's camera);
    the file's other tables (``[dataset]`` ...) are not read, so a data config serves
    ``simulate`` and ``simulate-sequence``.

    Raises
    ------
    ValueError
        A file holding neither (naming what a camera file holds), an unknown key in
        ``[camera]``, or a camera the optics refuse.
    """
    from ..config import _build, load_toml
    from ..optics.camera import PlenopticCamera
    from ..optics.camera_file import DATASHEET_KEYS, load_camera_file
    table = load_toml(path)
    if set(table) & set(DATASHEET_KEYS):
        return load_camera_file(path)
    if "camera" not in table and "dataset" in table:           # a data config of the paper's camera
        return PlenopticCamera()
    if "camera" not in table:
        raise ValueError(f"{path} describes no camera: a camera file holds the datasheet tables "
                         f"{', '.join(f'[{k}]' for k in DATASHEET_KEYS)} (docs/own_camera.md) or a [camera] table")
    return _build(PlenopticCamera, table["camera"], f"{path} [camera]")
