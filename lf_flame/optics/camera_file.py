"""A user's own camera from what its datasheets say, and the camera its decoded views come from.

A camera file (TOML) holds what one reads off the datasheets of the main lens, the
microlens array (MLA) and the sensor; :func:`camera_from_datasheet` turns it into a
:class:`~lf_flame.optics.camera.PlenopticCamera` (a non-perfect lenslet grid: its images
are ``p = pitch (1 + g/d) / pixel`` pixels apart, ``p`` in general not a whole number)::

    [main_lens]
    focal_length_mm = 100.0
    f_number = 10.0              # or aperture_mm = 10.0 (clear aperture diameter); neither: f-number matched
    focus_distance_mm = 200.0    # or mla_distance_mm = 200.0 (main lens to MLA); both: they must agree

    [microlens_array]
    pitch_um = 150.0
    focal_length_mm = 3.0        # the sensor sits at the lenslets' focus (plenoptic 1.0)
    layout = "square"            # or "hex"; optional, default "square"
    rotation_deg = 0.4           # optional: the calibration measures it
    offset_px = [0.0, 0.0]       # optional: grid centre from the sensor centre (rows, columns; px)
    rows = 40                    # optional lenslet counts; default: every lenslet whose image
    cols = 30                    #   lies whole on the sensor

    [sensor]
    pixel_size_um = 14.4
    rows = 480                   # sensor size, pixels
    cols = 360
    cfa = "RGGB"                 # optional: a colour (Bayer) sensor's 2 x 2 tile, row-major
    cfa_phase = [0, 0]           # optional: the tile's row and column at pixel (0, 0); default [0, 0]
    sensitivities = "Nikon 5100 (NPL)"   # optional: colour-science's camera sensitivities (the default)

``docs/own_camera.md`` describes the fields and the route from a white image to a
reconstruction; ``examples/own_camera.toml`` is a complete file.

Decoding (:func:`lf_flame.real.decoding.decode`) resamples every lenslet image at ``N``
points one pixel apart about its calibrated centre, along the grid's axes. Those views are
the views of another camera with a perfect grid (square, unrotated, ``N`` whole pixels per
lenslet): :func:`decoded_camera`. Its lenslets, main lens and aperture are the real ones;
its lenslet focal length ``g'`` is chosen so that one decoded pixel subtends the angle of
one real pixel, ``s'/g' = s/g`` (with ``s' = pitch (1 + g'/d) / N``), so every decoded
sample's rays meet the main lens where the real pixel's do and cross the MLA through the
same lenslet. What it leaves out is stated there.
"""
from __future__ import annotations

import math
import tomllib
import warnings
from pathlib import Path

from .camera import GRID_LAYOUTS, PITCH_SNAP_PX, PlenopticCamera, views_for_pitch

#: The keys of each table of a camera file: (required, optional).
DATASHEET_KEYS = {
    "main_lens": (("focal_length_mm",), ("f_number", "aperture_mm", "focus_distance_mm", "mla_distance_mm")),
    "microlens_array": (("pitch_um", "focal_length_mm"), ("layout", "rotation_deg", "offset_px", "rows", "cols")),
    "sensor": (("pixel_size_um", "rows", "cols"), ("cfa", "cfa_phase", "sensitivities")),
}
#: Relative disagreement tolerated between two values of the same quantity given twice
#: (f-number and aperture, focus distance and MLA distance): datasheets round to 3 digits.
AGREEMENT = 2e-3
#: Lenslet images whose pitch drifts from a whole number of pixels by at most this much across the sensor
#: (pixels) are whole: a datasheet's pitch for 13 px given to 8 decimals (13.0000007 px) had been refused as a grid
#: "13.000 px apart: not whole pixels" that must be decoded.
WHOLE_PITCH_DRIFT_PX = 0.01


def _number(where, key, v, *, integer=False, positive=True):
    ok = isinstance(v, int) if integer else isinstance(v, (int, float)) and not isinstance(v, bool)
    if not ok or isinstance(v, bool) or not math.isfinite(v) or (positive and v <= 0):
        kind = "a positive integer" if integer else ("a finite positive number" if positive else "a finite number")
        raise ValueError(f"{where}{key} must be {kind}. Received: {key}={v!r}")
    return int(v) if integer else float(v)


def _fit_grid(base: dict, rows, cols):
    """The camera of ``base`` with the given lenslet counts, or else the most lenslets whose
    whole images (centre +- half a pitch along each axis) lie on the sensor."""
    H, W = base["sensor_rows"], base["sensor_cols"]
    p, n = base["grid_pitch_px"], base["pixels_per_lenslet"]
    whole = abs(p - n) * max(H, W) / p <= WHOLE_PITCH_DRIFT_PX
    p = n if whole else p                                   # whole pixels to the datasheet's rounding
    hexa = base["grid_layout"] == "hex"
    r = rows if rows is not None else (int((H / p - 1) / (math.sqrt(3) / 2)) + 1 if hexa else int(H // p))
    c = cols if cols is not None else (int((W / p - 0.5) // 1) if hexa else int(W // p))
    free = {k: v for k, v in base.items() if k not in ("sensor_rows", "sensor_cols", "grid_offset_px")}
    free["grid_pitch_px"] = p
    off = base["grid_offset_px"]
    while r >= 1 and c >= 1:
        with warnings.catch_warnings():                                # a trial: the chosen camera warns
            warnings.simplefilter("ignore")
            cam = PlenopticCamera(**free, n_rows=r, n_cols=c)       # centred, sensor just holding it: valid
        rel = cam.lenslet_image_centres_px() - (cam.sensor_shape[0] / 2, cam.sensor_shape[1] / 2)
        lo, hi = rel.min(axis=(0, 1)) + off - p / 2, rel.max(axis=(0, 1)) + off + p / 2
        over_r = rows is None and bool(lo[0] < -H / 2 or hi[0] > H / 2)
        over_c = cols is None and bool(lo[1] < -W / 2 or hi[1] > W / 2)
        if not (over_r or over_c):
            if (whole and base["grid_rotation_deg"] == 0 and not any(off) and not hexa
                    and (H, W) == (r * n, c * n)):       # whole-pixel images tiling the sensor: a perfect grid
                keep = {k: v for k, v in free.items() if k not in ("grid_pitch_px", "grid_rotation_deg", "grid_layout")}
                return PlenopticCamera(**keep, n_rows=r, n_cols=c)
            return PlenopticCamera(**base, n_rows=r, n_cols=c)
        r, c = r - int(over_r), c - int(over_c)
    raise ValueError(f"no lenslet grid fits on the {H} x {W}-pixel sensor at a pitch of {p:.3f} px, offset {off} px")


def camera_from_datasheet(sheet: dict, where: str = "camera file") -> PlenopticCamera:
    """A plenoptic 1.0 camera from its datasheet values (the tables of a camera file).

    Parameters
    ----------
    sheet : dict
        Tables ``main_lens``, ``microlens_array`` and ``sensor`` with the keys of
        :data:`DATASHEET_KEYS` (module docstring): lengths in mm except the lenslet pitch
        and the pixel size (µm), the sensor size in pixels, the rotation in degrees.
    where : str
        Names the source in error messages.

    Returns
    -------
    PlenopticCamera
        A non-perfect grid: ``grid_pitch_px = pitch (1 + g/d) / pixel`` (the lenslet images'
        spacing: they are centred on the chief rays through the main lens's centre),
        ``pixels_per_lenslet`` the views per axis decoding takes
        (:func:`~lf_flame.optics.camera.views_for_pitch`), the given
        layout, rotation and offset, ``sensor_rows x sensor_cols`` pixels, the sensor at the
        lenslets' focus (``g`` = their focal length), ``d = 1 / (1/F - 1/z_f)``.

    Raises
    ------
    ValueError
        A missing table or key, an unknown one, a value that is not a positive number; the
        f-number and the aperture both given and disagreeing (beyond :data:`AGREEMENT`), the
        focus distance and the MLA distance both given and disagreeing, or neither given; a
        distance at or inside the main lens's focal length (no real image); lenslet images
        less than 2 pixels apart; an aperture whose image under a lenslet is less than 2
        pixels wide (no views); an unknown layout; no lenslet grid that fits on the sensor.

    Warns
    -----
    UserWarning
        The main lens is faster than the lenslets (its image under a lenslet is wider than
        the lenslet images' spacing): neighbouring images overlap (crosstalk), which the
        exact operator does not model.

    Notes
    -----
    Thin lenses, paraxial (Ng et al. 2005, plenoptic 1.0; the f-number matching of
    lenslet and main-lens images: Ng, Stanford CTSR 2005-02, Sec. 3.3).
    """
    if not isinstance(sheet, dict):
        raise ValueError(f"{where}: expected tables {sorted(DATASHEET_KEYS)}. Received: {type(sheet).__name__}")
    unknown = set(sheet) - set(DATASHEET_KEYS)
    if unknown:
        raise ValueError(f"{where}: unknown tables {sorted(unknown)} (a camera file has {sorted(DATASHEET_KEYS)})")
    t = {}
    for table, (required, optional) in DATASHEET_KEYS.items():
        d = sheet.get(table)
        if not isinstance(d, dict):
            raise ValueError(f"{where}: missing table [{table}] (keys {', '.join(required)} required)")
        bad = set(d) - set(required) - set(optional)
        if bad:
            raise ValueError(f"{where} [{table}]: unknown keys {sorted(bad)} (allowed: {sorted(required + optional)})")
        miss = [k for k in required if k not in d]
        if miss:
            raise ValueError(f"{where} [{table}]: missing {', '.join(miss)}")
        t[table] = d
    lens, mla, sensor = t["main_lens"], t["microlens_array"], t["sensor"]
    colour_sensor(t, where)                                          # a colour filter array named: checked now
    w = f"{where} [main_lens] "
    F = _number(w, "focal_length_mm", lens["focal_length_mm"])
    if "focus_distance_mm" not in lens and "mla_distance_mm" not in lens:
        raise ValueError(f"{w}needs focus_distance_mm (object in focus) or mla_distance_mm (main lens to MLA)")
    dists = {}
    for key in ("focus_distance_mm", "mla_distance_mm"):
        if key in lens:
            v = _number(w, key, lens[key])
            if v <= F:
                raise ValueError(f"{w}{key}={v} mm is at or inside the focal length {F} mm: the "
                                 + ("object's image would be at infinity or virtual" if key[0] == "f" else
                                    "MLA would see no real image of any object"))
            dists[key] = v
    z_f = dists.get("focus_distance_mm") or 1.0 / (1.0 / F - 1.0 / dists["mla_distance_mm"])
    d = 1.0 / (1.0 / F - 1.0 / z_f)
    if "mla_distance_mm" in dists and abs(dists["mla_distance_mm"] / d - 1) > AGREEMENT:
        raise ValueError(f"{w}focus_distance_mm={z_f} and mla_distance_mm={dists['mla_distance_mm']} disagree: a "
                         f"{F} mm lens focused at {z_f} mm puts its image {d:.3f} mm behind it (give one of them)")
    w = f"{where} [microlens_array] "
    pitch = _number(w, "pitch_um", mla["pitch_um"]) / 1000.0
    g = _number(w, "focal_length_mm", mla["focal_length_mm"])
    layout = mla.get("layout", "square")
    if layout not in GRID_LAYOUTS:
        raise ValueError(f"{w}layout must be one of {GRID_LAYOUTS}. Received: layout={layout!r}")
    rot = _number(w, "rotation_deg", mla.get("rotation_deg", 0.0), positive=False)
    off = mla.get("offset_px", [0.0, 0.0])
    if not isinstance(off, (list, tuple)) or len(off) != 2:
        raise ValueError(f"{w}offset_px must be two numbers (rows, columns; px). Received: offset_px={off!r}")
    off = tuple(_number(w, "offset_px", v, positive=False) for v in off)
    rows = None if "rows" not in mla else _number(w, "rows", mla["rows"], integer=True)
    cols = None if "cols" not in mla else _number(w, "cols", mla["cols"], integer=True)
    w = f"{where} [sensor] "
    s = _number(w, "pixel_size_um", sensor["pixel_size_um"]) / 1000.0
    H = _number(w, "rows", sensor["rows"], integer=True)
    W = _number(w, "cols", sensor["cols"], integer=True)
    p = pitch * (1.0 + g / d) / s
    if abs(p - round(p)) <= 1e-9 * p:
        p = float(round(p))                  # a whole number of pixels but for float rounding: a perfect grid
    if p < 2:
        raise ValueError(f"{where}: the lenslet images are {p:.3f} px apart (pitch {pitch * 1000:g} µm x (1 + g/d) / "
                         f"pixel {s * 1000:g} µm): fewer than 2 pixels per lenslet give no views; check the units "
                         "(pitch_um, pixel_size_um in micrometres)")
    w = f"{where} [main_lens] "
    D = None
    if "aperture_mm" in lens:
        D = _number(w, "aperture_mm", lens["aperture_mm"])
    if "f_number" in lens:
        D_f = F / _number(w, "f_number", lens["f_number"])
        if D is not None and abs(D / D_f - 1) > AGREEMENT:
            raise ValueError(f"{w}f_number={lens['f_number']} and aperture_mm={D} disagree: a {F} mm lens at "
                             f"f/{lens['f_number']} has a {D_f:.3f} mm aperture (give one of them)")
        D = D_f
    image_px = (d * pitch / g if D is None else D) * g / d / s      # the aperture's image under a lenslet, px
    if image_px < 2:
        given = "matched to the lenslets' f-number, no f_number or aperture_mm given" if D is None else "given"
        raise ValueError(f"{where}: the main lens's aperture ({d * pitch / g if D is None else D:.3g} mm, {given}) "
                         f"images onto {image_px:.2f} px under each lenslet: fewer than 2 views across it")
    if image_px > p * (1 + AGREEMENT):
        warnings.warn(f"{where}: the main lens (aperture {D:.3f} mm, image {image_px:.2f} px wide under a lenslet) is "
                      f"faster than the lenslets (images {p:.2f} px apart): neighbouring lenslet images overlap "
                      f"(crosstalk, not modelled by the exact operator); stop it down to f/{F * g / (d * pitch):.2f}",
                      UserWarning, stacklevel=2)
    base = dict(main_focal_mm=F, focus_distance_mm=z_f, mla_pitch_mm=pitch, mla_focal_mm=g,
                pixels_per_lenslet=views_for_pitch(p), aperture_mm=D, grid_pitch_px=p, grid_rotation_deg=rot,
                grid_offset_px=off, grid_layout=layout, sensor_rows=H, sensor_cols=W)
    try:
        return _fit_grid(base, rows, cols)
    except ValueError as e:
        raise ValueError(f"{where}: {e}") from None


def load_camera_file(path) -> PlenopticCamera:
    """The camera of a camera file (TOML): the datasheet tables (:func:`camera_from_datasheet`),
    or a ``[camera]`` table of :class:`~lf_flame.optics.camera.PlenopticCamera`'s own fields (as
    the data configs hold; a simulated camera).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not valid TOML, both kinds of tables, an unknown ``[camera]`` field, or the errors of
        :func:`camera_from_datasheet` and of the camera (naming the file).
    """
    p, sheet = _read_sheet(path)
    if "camera" in sheet:
        if set(sheet) & set(DATASHEET_KEYS) or not isinstance(sheet["camera"], dict):
            raise ValueError(f"camera file {p}: give a [camera] table or the datasheet tables "
                             f"{sorted(DATASHEET_KEYS)}, not both")
        try:
            return PlenopticCamera.from_dict(sheet["camera"])
        except (TypeError, ValueError) as e:
            raise ValueError(f"camera file {p} [camera]: {e}") from None
    return camera_from_datasheet(sheet, where=str(p))


def colour_sensor(sheet: dict, where: str = "camera file"):
    """The colour sensor a camera file's ``[sensor]`` table names, or None for a monochrome one.

    Parameters
    ----------
    sheet : dict
        A camera file's tables (:func:`camera_from_datasheet`); ``[sensor]`` may hold ``cfa``
        (a key of :data:`lf_flame.optics.colour.CFA_PATTERNS`, the 2 x 2 tile row-major),
        ``cfa_phase`` (the tile's row and column, 0 or 1, at pixel (0, 0); default [0, 0]) and
        ``sensitivities`` (a camera of colour-science's ``MSDS_CAMERA_SENSITIVITIES``; default
        :data:`lf_flame.optics.colour.DEFAULT_SENSITIVITIES`).
    where : str
        Names the source in error messages.

    Returns
    -------
    ColourSensor or None
        None where ``cfa`` is not given (``cfa_phase`` or ``sensitivities`` without it are refused).

    Raises
    ------
    ValueError
        An unknown pattern, a phase that is not two 0/1 integers, unknown sensitivities, or the
        colour keys without ``cfa``.
    """
    from .colour import CFA_PATTERNS, DEFAULT_SENSITIVITIES, library_sensor
    t = sheet.get("sensor", {}) if isinstance(sheet, dict) else {}
    w = f"{where} [sensor] "
    if "cfa" not in t:
        if "cfa_phase" in t or "sensitivities" in t:
            raise ValueError(f"{w}cfa_phase and sensitivities describe a colour filter array: give cfa too "
                             f"(one of {sorted(CFA_PATTERNS)})")
        return None
    if t["cfa"] not in CFA_PATTERNS:
        raise ValueError(f"{w}cfa must be one of {sorted(CFA_PATTERNS)}. Received: cfa={t['cfa']!r}")
    phase = t.get("cfa_phase", [0, 0])
    if (not isinstance(phase, list) or len(phase) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v in (0, 1) for v in phase)):
        raise ValueError(f"{w}cfa_phase must be two integers, 0 or 1 (row, column). Received: cfa_phase={phase!r}")
    try:
        return library_sensor(str(t.get("sensitivities", DEFAULT_SENSITIVITIES)), t["cfa"], tuple(phase))
    except ValueError as e:
        raise ValueError(f"{w}{e}") from None


def load_colour_sensor(path):
    """The colour sensor of a camera file (:func:`colour_sensor`), None for a monochrome one or a file of a
    ``[camera]`` table. Raises as :func:`load_camera_file` and :func:`colour_sensor`."""
    p, sheet = _read_sheet(path)
    return colour_sensor(sheet, str(p))


def _read_sheet(path):
    """A camera file's path and tables; FileNotFoundError or ValueError (not TOML) naming it."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"camera file not found: {p}")
    try:
        return p, tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"camera file {p} is not valid TOML: {e}") from None


def decoded_camera(camera: PlenopticCamera, n_views: int, n_rows: int, n_cols: int) -> PlenopticCamera:
    """The perfect-grid camera whose views are ``camera``'s decoded views.

    :func:`lf_flame.real.decoding.decode` samples each lenslet image at ``N`` points one
    (real) pixel apart about its centre, along the grid's axes, on an ``R x C`` square grid
    of lenslets. This returns a camera with a perfect grid (``N`` whole pixels per lenslet,
    square, unrotated), ``R x C`` lenslets, the same main lens, focus, aperture diameter and
    lenslet pitch, and a lenslet focal length (sensor distance) ``g'`` with
    ``1/g' = N s / (g pitch) - 1/d`` (``s``, ``g``, ``d``: the real pixel size, sensor
    distance and MLA distance). Then its pixel ``s' = pitch (1 + g'/d) / N`` subtends
    ``s'/g' = s/g``, the real pixel's angle: view ``(u, v)`` meets the main lens at the
    real decoded sample's height ``d (u - (N-1)/2) s / g`` and each of its rays crosses
    the same lenslet, so its light field is the decoded one.
    :class:`~lf_flame.tomo.exact.ExactOperator` takes it.

    Parameters
    ----------
    camera : PlenopticCamera
        The real camera (any grid), sensor at the lenslets' focus.
    n_views : int
        ``N``, decoded views per axis (``views.shape[0]``).
    n_rows, n_cols : int
        Lenslets of the decoded grid (``views.shape[2:]``).

    Returns
    -------
    PlenopticCamera
        ``perfect_grid`` True. For a perfect-grid ``camera`` decoded at its own ``N``, the
        same optics.

    Raises
    ------
    ValueError
        ``N`` not a positive integer or wider than the lenslet images (``N`` > their
        pitch in pixels), a grid size that is not a positive integer, a sensor away from
        the lenslets' focus, or optics for which no positive ``g'`` exists.

    Notes
    -----
    What is approximate (the decoded pixel is not the sensor pixel):

    - *Footprint.* A decoded sample is a bilinear interpolation of four sensor pixels:
      its footprint is the pixel widened by up to one pixel, varying from lenslet to
      lenslet with the sampling phase; the equivalent camera's pixel is one real pixel
      wide everywhere. The angular blur this adds grows with a plane's slope.
    - *Frame.* The equivalent camera is unrotated and its optical axis at the decoded
      grid's centre: its planes are the real ones turned by the grid's rotation about
      the axis, and shifted by the decoded grid's offset from the axis (object space;
      :func:`lf_flame.real.own_camera.decoded_frame`). cos⁴ is taken about the decoded
      grid's centre rather than the real axis; white-image division removes the real
      camera's cos⁴ and vignetting and :func:`lf_flame.tomo.decoded.decoded_problem` puts
      the model's back.
    - *Hexagonal grids* are resampled onto a square lattice of the same pitch
      (:func:`lf_flame.real.view_grid.hex_to_square`, barycentric): a spatial blur the
      equivalent camera does not have.
    - *Near the lenslet image's rim* a decoded sample mixes in pixels lit through the
      neighbouring lenslet; white-image division keeps them out only where the white is dark.
    """
    for name, v in (("n_views", n_views), ("n_rows", n_rows), ("n_cols", n_cols)):
        if isinstance(v, bool) or int(v) != v or v < 1:
            raise ValueError(f"{name} must be a positive integer. Received: {name}={v!r}")
    N = int(n_views)
    if N > camera.grid_pitch + PITCH_SNAP_PX:
        raise ValueError(f"{N} views per axis do not fit under lenslet images {camera.grid_pitch:.3f} px apart")
    g = camera.sensor_distance_mm
    if abs(g - camera.mla_focal_mm) > 1e-9:
        raise ValueError(f"the sensor is {g} mm behind the MLA, not at the lenslets' focus {camera.mla_focal_mm} mm: "
                         "decoded views are sub-aperture views of a plenoptic 1.0 camera only")
    d, pitch, s = camera.mla_distance_mm, camera.mla_pitch_mm, camera.pixel_pitch_mm
    inv = N * s / (g * pitch) - 1.0 / d
    if not inv > 0:
        raise ValueError(f"no perfect-grid camera has these {N} decoded views (1/g' = {inv:.3g} per mm)")
    return PlenopticCamera(main_focal_mm=camera.main_focal_mm, focus_distance_mm=camera.focus_distance_mm,
                           mla_pitch_mm=pitch, mla_focal_mm=1.0 / inv, pixels_per_lenslet=N,
                           n_rows=int(n_rows), n_cols=int(n_cols), aperture_mm=camera.aperture_diameter_mm)
