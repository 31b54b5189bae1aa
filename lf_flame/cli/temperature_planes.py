"""What the temperature commands share: each plane's temperature of one colour light field
(:mod:`lf_flame.temperature.channels` and :mod:`lf_flame.temperature.pyrometry`), its figure and file record,
the image's colour sensor, and the refusal of a light field without colour channels.

The colour sensor of an image (sensitivities, CFA pattern and phase) is, in order: the
``--sensor``/``--cfa``/``--cfa-phase`` options, the ``sensor`` record stored beside the raw
image (``.npz`` key or PNG text ``lf_flame.sensor``), the calibration's (``temperature``
only, said so), else colour-science's Nikon 5100 behind an RGGB CFA of phase (0, 0).
"""
from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from ._io import _load_raw, _raw_meta, refuse_rgb


def _sensor(path, a, cal=None):
    """The colour sensor of the image at ``path`` and a phrase saying where it came from: ``--sensor``, ``--cfa`` and
    ``--cfa-phase`` where given, else decoded views' stored sensor, a raw image's camera file's ``[sensor]`` (the CFA
    its decoding takes: :func:`lf_flame.real.readers.capture_sensor`) or stored record, the calibration's, the
    default."""
    from ..optics.colour import DEFAULT_SENSITIVITIES, library_sensor
    meta = _raw_meta(path)
    decoded = str(path).endswith(".h5") and Path(path).is_file()
    if decoded:                                                     # decoded views: the sensor decode stored
        import h5py
        with h5py.File(path, "r") as f:
            meta = {"sensor": str(f.attrs["sensor"])} if "sensor" in f.attrs else {}
    rec = json.loads(meta["sensor"]) if "sensor" in meta else {}
    where = f"stored in {path}"
    if not decoded and getattr(a, "camera", None):                  # a raw image decoded with its camera file
        from ..optics.camera_file import load_colour_sensor
        own = load_colour_sensor(a.camera)
        if own is not None:
            rec, where = dict(name=own.name, pattern=own.pattern, phase=tuple(own.phase)), f"{a.camera} [sensor]"
    given = {k: v for k, v in (("name", a.sensor), ("pattern", a.cfa),
                               ("phase", None if a.cfa_phase is None else tuple(a.cfa_phase))) if v is not None}
    moved = [k for k in ("pattern", "phase") if decoded and rec and k in given and
             (given[k] if k == "pattern" else tuple(given[k])) != (rec[k] if k == "pattern" else tuple(rec[k]))]
    if moved:
        raise ValueError(f"{path} holds views decoded with their channels apart at CFA {rec['pattern']} phase "
                         f"{tuple(rec['phase'])}: --cfa and --cfa-phase cannot move the channel map their samples "
                         "were cut with; decode the raw capture again with the camera file's cfa and cfa_phase")
    if not rec and cal is not None:
        rec = dict(name=cal.sensor_name, pattern=cal.pattern, phase=tuple(cal.phase))
        where = f"{path} records none: the calibration's"
    elif not rec:
        rec = dict(name=DEFAULT_SENSITIVITIES, pattern="RGGB", phase=(0, 0))
        where = f"{path} records none: the default"
    if given:
        where = "given" + ("" if len(given) == 3 else f" ({', '.join(given)}; the rest {where})")
    rec = {**rec, **given}
    return library_sensor(rec["name"], rec["pattern"], tuple(rec["phase"])), where


def _refuse_monochrome(path):
    """Refuse a light field without colour channels: one ``lf-flame simulate`` rendered monochrome
    (its record holds a camera and no sensor), or an image whose four 2 x 2 pixel phases have the
    same mean over its lit pixels (:func:`lf_flame.temperature.mosaic.refuse_no_mosaic`): no mosaic to take a ratio
    of. Returns the raw image it read (rows, cols)."""
    refuse_rgb(path)
    meta = _raw_meta(path)
    if "camera" in meta and "sensor" not in meta:
        raise ValueError(f"{path} is a monochrome light field (rendered without a colour sensor): two-colour "
                         "pyrometry needs a colour (Bayer) capture")
    from ..temperature.mosaic import refuse_no_mosaic
    raw = _load_raw(path)[0]
    refuse_no_mosaic(raw, path)
    return raw


def furnace_note(path, alpha: float):
    """A note (stderr) where ``path`` is a furnace image ``lf-flame simulate`` rendered (a blackbody filling the
    field), or views decoded from one, and ``alpha`` (the emissivity exponent) is not 0: a blackbody's emissivity is
    flat in wavelength, and soot's exponent (the default) reads it 9-10 % low (1,636 K for 1,800 K). Returns
    whether it noted."""
    meta = _raw_meta(path)
    p = Path(str(path))
    if not meta and p.suffix.lower() == ".h5" and p.is_file():          # decoded views: the raw image they came from
        import h5py
        with h5py.File(p, "r") as f:
            source = f.attrs.get("raw")
        meta = _raw_meta(source) if source is not None else {}
    kind = json.loads(meta["scene"]).get("kind") if "scene" in meta else None
    if kind != "furnace" or alpha == 0:
        return False
    print(f"note: {path} is a furnace image (a blackbody): its emissivity is flat in wavelength, so give --alpha 0; "
          f"--alpha {alpha:g} (soot's exponent, the default) reads a blackbody 9-10 % low", file=sys.stderr)
    return True


#: What the temperature figure's grey area is (its legend entry).
NO_TEMPERATURE = "no temperature: dim, or a ratio outside the calibration"


def temperature_figure(temperature_k, depths_mm, valid, camera=None, truth_k=None):
    """``temperature``'s figure: each plane's temperature map in object-space mm, one colour bar in K.

    Pixels without a temperature (NaN) are grey, named by a legend entry (:data:`NO_TEMPERATURE`).
    With a truth, its maps form a second row on the same colour scale.

    Parameters
    ----------
    temperature_k : ndarray of shape (P, rows, cols)
        Temperature (K), NaN where none was estimated.
    depths_mm : sequence of P float
        The planes' depths (mm from the focal plane).
    valid : ndarray of bool, shape (P, rows, cols)
        Where a temperature was estimated (counted in the titles).
    camera : PlenopticCamera or None
        The planes' camera: axes in mm (:func:`lf_flame.measure.figures.plane_extent_mm`); None: lenslets.
    truth_k : ndarray of shape (P, rows, cols) or None
        The true temperature (K) on the same planes, NaN where the scene has none.

    Returns
    -------
    matplotlib.figure.Figure
        Axes: the panels row by row (estimate, then truth), then the colour bar's.
    """
    from ..measure.figures import plane_extent_mm, planes_figure, signed
    t = np.asarray(temperature_k, float)
    rows = [t] if truth_k is None else [t, np.asarray(truth_k, float)]
    finite = np.concatenate([r[np.isfinite(r)] for r in rows])
    lo, hi = np.percentile(finite, [1, 99]) if finite.size else (1500.0, 2500.0)
    extents = None if camera is None else [plane_extent_mm(camera, d) for d in depths_mm]
    titles = [[f"estimate {signed(d)} mm\n{int(np.sum(v))} px with T" for d, v in zip(depths_mm, valid)],
              [f"truth {signed(d)} mm" for d in depths_mm]][:len(rows)]
    return planes_figure(rows, extents, titles, "temperature (K)", vmin=float(lo), vmax=float(max(hi, lo + 1)),
                         bad_label=NO_TEMPERATURE)


def _level_record(saturation, lf) -> str | float:
    """What ``--saturation`` the file records: the level used (found in a raw image where 'auto'), or what a decoded
    capture's clipped samples came from."""
    if lf.decoded:
        return "decoded: the views' clipped samples"
    level = lf.saturation if saturation == "auto" else saturation
    return "none" if level is None else float(level)


def _plane_temperatures(a, lf, depths, found, cal, sensor, cache=None) -> dict:
    """Each plane's temperature of one colour light field ``lf`` on ``depths`` (``found``: the
    :class:`~lf_flame.tomo.depth.FoundDepths` they came from, or None) by ``a.route``: the channels' emission
    (:func:`lf_flame.temperature.channels.channel_emission`) and their ratio through ``cal``
    (:func:`lf_flame.temperature.pyrometry.temperature_planes`). ``cache``: a dict that keeps what the next light field
    of the same camera and planes (a recording's frames) shares: the route's operator, a raw mosaic's channel map and
    the found planes' support.

    Returns
    -------
    dict
        ``temp`` (P, R, C) K, NaN where none; ``valid``, ``dim`` (P, R, C) bool; ``n_masked``, ``n_dim`` (P,);
        ``emission`` (2, P, R, C); ``chosen`` (the route's settings); ``slopes``, ``blind`` (P,); ``sample`` (P, 2) mm.
    """
    from ..measure.diagnostics import lenslet_size_mm
    from ..optics.colour import CHANNELS
    from ..temperature.pyrometry import bright_pixels, temperature_planes
    from ..temperature.channels import (DECODED_KNOBS, DECODED_OFFSET_KNOBS, DECODED_RATIO_FILTER, channel_emission,
                                        route_operator)
    from ..temperature.mosaic import channel_views
    from ..tomo.decoded import fit_data
    cam, views = lf.camera, lf.views
    n = cam.pixels_per_lenslet
    cache = {} if cache is None else cache
    if not lf.decoded and "chan" not in cache:
        cache["chan"] = channel_views((views.shape[2] * n, views.shape[3] * n), sensor, n)
    chan = lf.channels if lf.decoded else cache["chan"]
    ch = tuple(CHANNELS.index(c) for c in cal.channels)
    hexagonal = lf if lf.lattice_views is not None and lf.channels is not None else None
    chosen, knobs, ratio_filter = {}, None, None
    slopes = [cam.slope_for_depth(d) for d in depths]
    if "op" not in cache:
        cache["op"] = route_operator(cam, depths, a.route, hexagonal, lf.sample_offsets if hexagonal is None else None)
    op = cache["op"]
    if getattr(op, "offset_bins", None):                # each sample at its own pixel: recorded with the route
        chosen["sub_views"] = op.offset_bins
    if not lf.decoded:                                  # the level given, and the image's defective pixels
        given = lf if a.saturation == "auto" else dataclasses.replace(lf, saturation=a.saturation)
        data, sat = views, given.fit_mask()
    elif op is None:                                    # refocus-cfa: the decoded views as they are
        data, sat = views, None
    elif hexagonal is not None:                         # the lattice's views (axial), its channels with them
        from ..tomo.lattice import lattice_problem, to_axial
        data, sat = lattice_problem(lf, op)
        chan = np.where(op.inside, to_axial(chan)[0], -1).astype(np.int8)
    else:                                               # the operator's data: views times its white views
        data, sat = fit_data(lf, op)
    if lf.decoded and a.route == "admm-cfa-matched":    # a decoded capture's knobs, not its noise's
        knobs, ratio_filter = DECODED_OFFSET_KNOBS if op.offset_bins else DECODED_KNOBS, DECODED_RATIO_FILTER
        chosen["regime"] = "decoded"
    support = None
    if found is not None and op is not None:
        # found planes near each other held to their own regions where they meet, as reconstruct holds them (a
        # hexagonal grid's taken from the decoded square grid to its lattice)
        if "support" not in cache:
            from ..tomo.found_planes import found_support
            support = found_support(found, cam, op.subsamples)
            cache["support"] = op.from_square(support) if support is not None and hexagonal is not None else support
        support = cache["support"]
        chosen["support"] = "none" if support is None else "near planes"
    emission = channel_emission(a.route, data, chan, ch, op=op, slopes=slopes, saturation=sat, info=chosen,
                                knobs=knobs, ratio_filter=ratio_filter, support=support)
    if hexagonal is not None:                           # the lattice's planes on the decoded square grid
        emission = tuple(op.to_square(e, cam.n_rows, cam.n_cols) for e in emission)
        chosen["lattice"] = "hexagonal"
    temp, valid, n_masked = temperature_planes(emission[0], emission[1], cal, sensor, a.alpha, a.min_fraction)
    dim = ~bright_pixels(emission[0] + emission[1], a.min_fraction)
    return dict(temp=temp, valid=valid, n_masked=n_masked, dim=dim, n_dim=dim.reshape(len(dim), -1).sum(axis=1),
                emission=emission, chosen=chosen, slopes=slopes, blind=_blind(lf, slopes, n),
                sample=np.array([[lenslet_size_mm(cam, d)] * 2 for d in depths]))


def _blind(lf, slopes, n) -> np.ndarray:
    """:func:`lf_flame.temperature.mosaic.cfa_blind` of the planes, where the capture's CFA phase alternates with its
    lenslets as that rule has it (a perfect grid of N pixels per lenslet); a capture of a real grid (a pitch of no
    whole number of pixels, rotated, hexagonal) shifts the phase from lenslet to lenslet otherwise, and no plane is
    blind: a user's decoded planes at slopes 0.83 and 1.04 had been warned of, each of its lenslets holding 13 red
    samples or more."""
    from ..temperature.mosaic import cfa_blind
    if lf.decoded and not lf.capture_camera.perfect_grid:
        return np.zeros(len(slopes), bool)
    return cfa_blind(slopes, n)


def given_planes_found(a, lf, depths):
    """The depth search of the colour light field ``lf``'s channels levelled into one
    (:func:`lf_flame.temperature.mosaic.monochrome_light_field`, :func:`lf_flame.cli.planes.given_planes_search`) for
    planes the user gave: ``(found, held)``, ``held`` its regions put on given planes near each other
    (:func:`lf_flame.cli.planes.given_planes_held`), so that :func:`_plane_temperatures` holds them to their own
    regions as it holds found ones (else each reads the other's flame at temperatures of its own). For the admm routes
    (``refocus-cfa`` solves nothing). Chosen on the example colour camera's validation captures
    (``experiments/cameras_colour.py --seed0 58100``, the flames' true depths; a ``/tmp`` probe): worst-plane p90
    median / worst 82 / 117 -> 72 / 127 K noise-free and 104 / 178 -> 82 / 120 K at 14 dB; the pixels reported where
    the truth has no flame 40 -> 25 % and 42 -> 28 %."""
    from ..temperature.mosaic import monochrome_light_field
    from .planes import given_planes_held, given_planes_search
    found = given_planes_search(monochrome_light_field(lf), a.search_range)
    held = given_planes_held(found, lf.camera, depths)
    if held is not None:
        print("the planes given lie within a few lenslets of parallax of each other: each held to the regions of the "
              "depths found nearest it")
    return found, held


def _auto_depths(a, lf):
    """``--depths auto``: reconstruct's planes of the colour light field ``lf`` (its channels levelled, the depths
    found, the residual searched, refined): (depths, found, the record's extra attributes, with
    :func:`fit_warnings`')."""
    from ..temperature.mosaic import monochrome_light_field
    from .planes import found_planes, found_record, possible_warning, solve_found
    mono = monochrome_light_field(lf)
    _, _, found = found_planes(mono, search_range=a.search_range)
    found, op, rec = solve_found(mono, found)
    extra = dict(depths_from="auto (as reconstruct: the channels levelled, depths found, the residual searched, "
                             "refined)", found_depths=found_record(found), possible_depths=possible_warning(found))
    extra.update(fit_warnings(a, lf, found.planes_mm, (op, rec), found))
    return [float(d) for d in found.planes_mm], found, extra


def fit_warnings(a, lf, depths, solved=None, found=None, given=None) -> dict:
    """``reconstruct``'s warnings on the colour light field ``lf``'s planes: its channels levelled into one light
    field and solved there (or ``solved``, the ``(op, rec)`` of that solve; ``found``: the found planes, or the
    given ones held to the depth search's regions, :func:`given_planes_found`), the share of each plane's emission at
    the field's edge and the misfit (:func:`lf_flame.cli.fit_notes.edge_warning`,
    :func:`~lf_flame.cli.fit_notes.misfit_warning`): planes where no flame stands, a flame missed or cut by the
    field, which the temperatures alone do not show; and the share of its lit pixels that clip
    (:func:`lf_flame.cli.real.overexposure_warning`, a note below its level); for planes the user gave, those where
    the depth search (``given``, :func:`given_planes_found`) finds no flame and the data need none
    (:func:`lf_flame.cli.fit_notes.plane_warnings`). Returns the record's ``edge_share``, ``misfit``,
    ``clipped_share`` and, with ``given``, ``planes_without_flame``."""
    from ..real.clipping import CLIPPED_WARN
    from ..temperature.mosaic import monochrome_light_field
    from .fit_notes import plane_warnings
    from .planes import _fitted_light_field, lattice_solve, run_reconstruction
    from .real import overexposure_warning
    mono = monochrome_light_field(lf)
    level = "file" if a.saturation == "auto" else a.saturation         # the light field's own, or the level given
    op, rec = solved if solved is not None else run_reconstruction(mono, [float(d) for d in depths], saturation=level,
                                                                   found_depths=found)
    rec, lattice = lattice_solve(_fitted_light_field(mono, level), op, rec, found)
    clipped = overexposure_warning(lf.over_exposure())
    if 0 < clipped <= CLIPPED_WARN:     # under reconstruct's warning, yet a ratio's two channels clip apart
        print(f"note: {100 * clipped:.2g} % of the lit pixels are clipped and left out of the fit: the brightest "
              "emission's temperatures rest on fewer samples there (one channel clips before the other)",
              file=sys.stderr)
    return dict(clipped_share=clipped, **plane_warnings(mono, op, rec, lattice, level, given))


def _plane_lines(a, depths, r, cal=None) -> list:
    """The printout's line per plane: its pixels with a temperature, their median and p10-p90, and the pixels left
    without one (:func:`_plane_temperatures`' ``r``); with the calibration ``cal`` (of two temperatures or more), the
    share of the temperatures beyond its blackbodies' range (the sensor's model carries the ratio there, unchecked)."""
    from ..temperature.pyrometry import T_RANGE_K
    fit = sorted(set(cal.fit_temperatures_k)) if cal is not None else []
    lines = []
    for k, d in enumerate(depths):
        v = r["temp"][k][r["valid"][k]]
        stats = (f"median {np.median(v):.0f} K, p10-p90 {np.percentile(v, 10):.0f}-{np.percentile(v, 90):.0f} K"
                 if v.size else "no temperature")
        if v.size and len(fit) > 1:
            out = float(np.mean((v < fit[0]) | (v > fit[-1])))
            if out > 0:
                stats += (f" ({100 * out:.2g} % beyond the blackbodies' {fit[0]:g}-{fit[-1]:g} K: extrapolated by the "
                          "sensor's model)")
        lines.append(f"plane {k} ({d:+.2f} mm): {int(r['valid'][k].sum())} px with a temperature, {stats}; "
                     f"{int(r['n_masked'][k])} bright px masked (ratio outside the table's {T_RANGE_K[0]:g}-{T_RANGE_K[1]:g} K), "
                     f"{int(r['n_dim'][k])} px "
                     f"below {a.min_fraction:g} of the peak"
                     + (f"; WARNING: slope {r['slopes'][k]:+.3f} near an odd integer, half its lenslets have no red "
                        "sample in any view (cfa_blind): its temperature is interpolation there" if r["blind"][k]
                        else ""))
    return lines


def _record(a, cal, sensor, where, chosen) -> dict:
    """What a temperature file records of its calibration, sensor and route (HDF5 attributes)."""
    return dict(calibration=json.dumps(dict(path=str(a.calibration),
                                            **{k: getattr(cal, k) for k in cal.__dataclass_fields__})),
                sensor=json.dumps(dict(sensor.record(), where=where)),
                route=a.route, route_settings=json.dumps(chosen), alpha=float(a.alpha),
                min_fraction=float(a.min_fraction))


def _sensor_args(s, calibration_default):
    s.add_argument("--sensor", help="camera sensitivities (a name of colour-science's MSDS_CAMERA_SENSITIVITIES, "
                   "e.g. 'Nikon 5100 (NPL)'); default: the image's stored sensor record"
                   + (", else the calibration's" if calibration_default else "") + ", else Nikon 5100 (NPL)")
    s.add_argument("--cfa", choices=["RGGB", "BGGR", "GRBG", "GBRG"], help="colour filter array (default: as "
                   "--sensor)")
    s.add_argument("--cfa-phase", type=int, nargs=2, metavar=("ROW", "COL"),
                   help="tile row and column (0 or 1) of pixel (0, 0) (default: as --sensor, else 0 0)")
