"""The lenslet-grid check of a raw image against its calibration (:func:`lf_flame.real.grid_check.check_grid`):
a capture of the calibrated camera passes whatever it shows; a capture of another grid is refused,
naming the grid it shows.

The cameras are ``examples/own_camera.toml`` (10.57 px pitch, rotated 0.4°, on a 520 x 340 px
sensor) with a square or a hexagonal grid and other lenslet pitches, as ``experiments/cameras.py``
builds them; the captures are its ``simulate --scene depth`` scenes (flames at random depths).
"""
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from lf_flame.optics.camera_file import camera_from_datasheet
from lf_flame.real import calibration as calibrate
from lf_flame.real import decoding as decode
from lf_flame.real import view_grid
from lf_flame.real.grid_check import check_grid
from lf_flame.simulate import scenes, tracer
from lf_flame.simulate.scenes_depth import camera_depth_scene

EXAMPLE = tomllib.loads((Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text())
RAYS = 16
#: The scene of experiments/cameras.py whose captures the hexagonal camera's calibration refused
#: (two flames of 0.9 mm out of focus: the strongest peak of period 9.91 px, the grid's 9.16 px).
SEED = 56003


def _camera(layout, pitch_um=150.0):
    """The example camera with another grid; the main lens stopped down to the lenslets where they are smaller."""
    lens = {**EXAMPLE["main_lens"], "f_number": EXAMPLE["main_lens"]["f_number"] * max(1.0, 150.0 / pitch_um)}
    return camera_from_datasheet({**EXAMPLE, "main_lens": lens,
                                  "microlens_array": {**EXAMPLE["microlens_array"], "layout": layout,
                                                      "pitch_um": pitch_um}})


@pytest.fixture(scope="module")
def grids():
    """``grids(layout, pitch_um)``: (camera, its white image, a depth capture), rendered once."""
    made = {}

    def get(layout, pitch_um=150.0):
        if (layout, pitch_um) not in made:
            cam = _camera(layout, pitch_um)
            white = tracer.render(cam, scenes.white_scene(cam), RAYS, 0)
            raw = tracer.render(cam, camera_depth_scene(cam, np.random.default_rng(SEED)), RAYS, SEED)
            made[layout, pitch_um] = cam, white, raw
        return made[layout, pitch_um]
    return get


@pytest.fixture(scope="module")
def calibrations(grids):
    made = {}

    def get(layout):
        if layout not in made:
            made[layout] = calibrate.calibrate(grids(layout)[1])
        return made[layout]
    return get


@pytest.mark.parametrize("layout", ["hex", "square"])
def test_a_capture_of_the_calibrated_camera_passes(grids, calibrations, layout):
    """Flames out of focus light part of each lenslet image, a part that moves from lenslet to
    lenslet: the hexagonal capture's strongest peak is off the grid's reciprocal lattice (at
    16 times the power of its fundamentals); the grid's harmonics stay on it, and it passes."""
    cam, white, raw = grids(layout)
    cal = calibrations(layout)
    assert cal.layout == layout and abs(cal.pitch_px / cam.grid_pitch_px - 1) < 1e-3
    check_grid(raw, cal)
    check_grid(white, cal)
    views = decode.decode(raw, cal, white)               # decode checks the grid too
    assert np.isfinite(views).all() and views.max() > 0
    rng = np.random.default_rng(1)                       # with shot and read noise (about 14 dB)
    noisy = rng.poisson(200 * raw) / 200 + 0.05 * raw.max() * rng.standard_normal(raw.shape)
    check_grid(noisy, cal)


@pytest.mark.parametrize("calibrated, shown", [
    ("hex", ("square", 150.0)),            # the other layout, same pitch
    ("square", ("hex", 150.0)),
    ("hex", ("hex", 135.0)),               # 0.9 x the pitch
    ("hex", ("hex", 165.0)),               # 1.1 x
    ("square", ("square", 165.0)),
], ids=str)
def test_a_capture_of_another_grid_is_refused(grids, calibrations, calibrated, shown):
    cal = calibrations(calibrated)
    cam, white, raw = grids(*shown)
    for img in (raw, white):
        with pytest.raises(ValueError, match="another camera") as err:
            check_grid(img, cal)
        got = re.search(r"shows a (\w+) lenslet grid of pitch ([\d.]+) px", str(err.value))
        assert got and got[1] == cam.grid_layout, str(err.value)
        assert abs(float(got[2]) / cam.grid_pitch_px - 1) < 0.03, str(err.value)    # a bin at the fundamentals


@pytest.mark.parametrize("layout", ["hex", "square"])
def test_a_calibration_whose_grid_lies_off_the_lenslet_images_is_refused(grids, calibrations, layout):
    """The grid's origin moved by half a pitch (a hand edit, or a lenslet array that moved since calibration): the
    white image's brightest view is no longer the central one, and decoding refuses it. The grid check (pitch and
    layout) cannot see it, and such views had been 55 % off, six planes found for four flames. The calibration's own
    white image passes, its brightest view central."""
    import dataclasses
    cam, white, raw = grids(layout)
    cal = calibrations(layout)
    assert np.abs(np.array(np.unravel_index(decode.white_samples(cal, white).mean(axis=(2, 3)).argmax(),
                                            (10, 10))) - 4.5).max() <= 1.5
    moved = dataclasses.replace(cal, origin_px=(cal.origin_px[0] + cal.pitch_px / 2, cal.origin_px[1]))
    with pytest.raises(ValueError, match="lenslet grid lies off the lenslet images"):
        decode.decode(raw, moved, white)


def test_a_dark_image_cannot_be_checked_and_passes(calibrations):
    cal = calibrations("hex")
    check_grid(np.zeros(cal.sensor_shape), cal)
    check_grid(np.random.default_rng(0).normal(size=cal.sensor_shape), cal)


@pytest.mark.parametrize("depth_mm", [-10.0, 10.0, 20.0])
def test_a_point_of_light_cannot_be_checked_and_passes(calibrations, depth_mm):
    """A point source out of focus lights one or two lenslet images' worth of pixels (:func:`lit_lenslets`), whose
    few peaks fit other grids as well as the calibration's: its capture was refused (pitches of 8.0, 9.6 and
    12.1 px seen against the calibration's 10.57 px) and decodes now; a capture of flames of another grid is still
    refused (above)."""
    from lf_flame.real.grid_check import GRID_CHECK_MIN_LIT, lit_lenslets
    cam = _camera("square")
    cal = calibrations("square")
    raw = tracer.render(cam, scenes.point_scene(cam, depth_mm, y_mm=-1.0), 64, 7)
    assert 0 < lit_lenslets(raw, cal.pitch_px) < GRID_CHECK_MIN_LIT
    check_grid(raw, cal)


def test_each_colour_samples_offset_leads_from_its_view_to_its_pixel(calibrations):
    """:func:`~lf_flame.real.view_grid.sample_offsets`: the view's place plus its offset (turned back onto the
    sensor) is the centre of the pixel decode_colour reads, each offset within half a step (a little more on a
    rotated grid) and spread over the whole step on a non-integer pitch, on either lattice."""
    for layout in ("square", "hex"):
        cal = calibrations(layout)
        off = view_grid.sample_offsets(cal, 9)
        pos = view_grid.view_positions(cal, 9)
        back = pos + off.astype(np.float64) @ (cal.matrix / cal.pitch_px).T
        assert np.allclose(back, np.floor(pos) + 0.5, atol=1e-5)
        assert off.shape == pos.shape and np.abs(off).max() <= 0.5 * (1 + np.tan(np.radians(0.5)))
        assert np.percentile(off, 5) < -0.4 and np.percentile(off, 95) > 0.4


def test_the_decoders_bilinear_samples_are_scipys_map_coordinates():
    """:func:`~lf_flame.real.decoding._sample` (its Numba kernel, one pass for a stack of images) gives
    ``scipy.ndimage.map_coordinates(order=1, mode="constant")`` at pixel centres shifted by ½: bilinear inside,
    0 beyond either axis's first or last pixel centre, on every image of a stack and on a single image alike;
    the positions keep their leading shape."""
    from scipy import ndimage
    rng = np.random.default_rng(7)
    images = rng.random((3, 23, 17))
    pos = rng.uniform(-1.0, 25.0, (5, 40, 2))
    pos[0, :8] = [[0.5, 0.5], [22.5, 16.5], [22.5, 3.0], [4.0, 16.5],             # the first and last centres
                  [0.5 - 1e-9, 3.0], [4.0, 16.5 + 1e-9], [22.6, 0.7], [0.4, 0.4]]   # just beyond them
    want = np.array([ndimage.map_coordinates(im, np.moveaxis(pos, -1, 0) - 0.5, order=1, mode="constant", cval=0.0)
                     for im in images])
    got = decode._sample(images, pos)
    assert got.shape == (3, 5, 40) and np.allclose(got, want, rtol=0, atol=1e-14)
    assert np.array_equal(got[:, 0, 4:8] == 0, np.ones((3, 4), bool)) and np.all(got[:, 0, :4] > 0)
    assert 0.2 < np.mean(want == 0) < 0.6                                   # both kinds of position drawn
    assert np.allclose(decode._sample(images[1], pos), want[1], rtol=0, atol=1e-14)


def test_view_positions_are_shared_for_one_grid_and_read_only(calibrations):
    """:func:`~lf_flame.real.view_grid.view_positions` hands the same read-only array to every call for one grid and
    view count (a recording's frames), and new positions for another grid or count."""
    import dataclasses
    cal = calibrations("square")
    a, b = view_grid.view_positions(cal, 5), view_grid.view_positions(cal, 5)
    assert a is b and not a.flags.writeable
    with pytest.raises(ValueError):
        a[0, 0, 0, 0, 0] = 1.0
    moved = dataclasses.replace(cal, origin_px=(cal.origin_px[0] + 0.25, cal.origin_px[1]))
    c = view_grid.view_positions(moved, 5)
    assert c is not a and np.allclose(c[..., 0] - a[..., 0], 0.25) and np.array_equal(c[..., 1], a[..., 1])
    assert view_grid.view_positions(cal, 3).shape[:2] == (3, 3)


@pytest.mark.parametrize("layout", ["hex", "square"])
def test_a_white_images_samples_decode_as_the_white_image_does(grids, calibrations, layout):
    """The views are the capture's samples over the white image's (both dark-subtracted, sampled bilinearly at
    the views' positions as SciPy samples them, binned), 0 where the white's are at or below 5 % of their 99th
    percentile; ``decode(white_views=white_samples(...))`` (a recording's white image sampled once) gives them bit
    for bit as ``decode(white=...)`` does, with a dark frame and binned; both at once, or samples of another
    binning, are refused."""
    from scipy import ndimage
    _, white, raw = grids(layout)
    cal = calibrations(layout)
    dark = np.full(raw.shape, 0.01)
    for k in (1, 2):
        want = decode.decode(raw + dark, cal, white + dark, dark, bin_views=k, resample=False)
        n = want.shape[0]
        pos = np.moveaxis(view_grid.view_positions(cal, n * k), -1, 0) - 0.5

        def sampled(img):
            s = ndimage.map_coordinates(np.asarray(img, np.float64), pos.reshape(2, -1), order=1,
                                        mode="constant").reshape(pos.shape[1:])
            return s.reshape(n, k, n, k, *s.shape[2:]).sum(axis=(1, 3))
        rv, wv0 = sampled(raw), sampled(white)
        lit = wv0 > 0.05 * np.percentile(wv0, 99)
        assert np.allclose(want, np.where(lit, rv / np.where(lit, wv0, 1.0), 0.0), rtol=1e-6, atol=1e-7)
        wv = decode.white_samples(cal, white + dark, dark, bin_views=k)
        assert np.array_equal(wv > 0, lit) and np.allclose(wv[lit], wv0[lit], rtol=1e-12, atol=0)
        assert np.array_equal(decode.decode(raw + dark, cal, None, dark, bin_views=k, resample=False,
                                            white_views=wv), want)
    with pytest.raises(ValueError, match="not both"):
        decode.decode(raw, cal, white, white_views=wv)
    with pytest.raises(ValueError, match="white_views of shape"):
        decode.decode(raw, cal, white_views=wv)                 # binned by 2, the views not


@pytest.mark.parametrize("layout", ["hex", "square"])
def test_a_colour_white_images_samples_decode_as_the_white_image_does(grids, calibrations, layout):
    """A colour capture's views over its white image (each sample its nearest pixel, over its channel's 99th
    percentile on the sensor, 0 at or below 5 %): ``decode_colour(white_views=white_samples(..., sensor=...))``,
    a recording's white image sampled once, gives them bit for bit as ``decode_colour(white=...)``, with a dark
    frame; both at once, or binned samples of a colour sensor, are refused."""
    from lf_flame.optics.colour import library_sensor
    _, white, raw = grids(layout)
    cal = calibrations(layout)
    sensor = library_sensor(pattern="RGGB", phase=(1, 0))
    dark = np.full(raw.shape, 0.01)
    want, channels = decode.decode_colour(raw + dark, cal, sensor, white + dark, dark)
    wv = decode.white_samples(cal, white + dark, dark, sensor=sensor)
    got, got_channels = decode.decode_colour(raw + dark, cal, sensor, None, dark, white_views=wv)
    assert np.array_equal(got, want) and np.array_equal(got_channels, channels) and np.any(want)
    assert np.all(want[wv == 0] == 0) and 0 < np.mean(wv == 0) < 1                   # 0 where the white is dark
    mono = decode.white_samples(cal, white + dark, dark)             # bilinear, one level for all pixels
    assert mono.shape == wv.shape and not np.allclose(mono, wv)
    with pytest.raises(ValueError, match="not both"):
        decode.decode_colour(raw, cal, sensor, white, white_views=wv)
    with pytest.raises(ValueError, match="bin_views 1"):
        decode.white_samples(cal, white, sensor=sensor, bin_views=2)


@pytest.mark.parametrize("layout", ["hex", "square"])
def test_clipped_samples_of_a_capture_without_a_clipped_pixel_are_none_in_the_views_shape(grids, calibrations,
                                                                                         layout):
    """A capture with no pixel at the level and no defect marks no sample, in the shape of the views it decodes to
    (on the square grid or the hexagonal lattice, binned or not); one clipped pixel marks the samples it feeds."""
    _, white, raw = grids(layout)
    cal = calibrations(layout)
    level = 2.0 * float(raw.max())
    for k, resample in ((1, True), (1, False), (2, False)):
        views = decode.decode(raw, cal, white, bin_views=k, resample=resample)
        none = decode.clipped_samples(raw, cal, level, bin_views=k, resample=resample)
        assert none.shape == views.shape and none.dtype == bool and not none.any()
    spot = np.unravel_index(np.argmax(raw), raw.shape)
    one = raw.copy()
    one[spot] = level
    hit = decode.clipped_samples(one, cal, level, resample=False)
    assert 1 <= hit.sum() <= 12               # the samples within a pixel of it: 2 x 2 views of the lenslets it reaches


@pytest.mark.parametrize("layout", ["square", "hex"])
def test_a_white_image_with_dust_decodes_and_its_dark_lenslets_are_named(grids, calibrations, layout, tmp_path,
                                                                          capsys):
    """A dust spot on the white image (a disc dimmed to 0.4 of its light): decoding takes it (the views' means are
    flat-topped, and on the hexagonal grid the brightest view moved 2.8 views out: refused as a grid off the lenslet
    images), and calibrate names its dark lenslets, where it said nothing; the clean white image has none."""
    from lf_flame.cli import main
    cam, white, raw = grids(layout)
    cal = calibrations(layout)
    H, W = white.shape
    yy, xx = np.mgrid[:H, :W]
    dusty = white * np.where(np.hypot(yy - 0.4 * H, xx - 0.6 * W) < 0.06 * min(H, W), 0.4, 1.0)
    views = decode.decode(raw, cal, dusty)
    assert np.isfinite(views).all()
    assert not decode.dark_lenslets(decode.white_samples(cal, white)).any()
    n = int(decode.dark_lenslets(decode.white_samples(cal, dusty)).sum())
    assert 5 <= n <= 40, n
    np.save(tmp_path / "dusty.npy", dusty.astype(np.float32))
    assert main(["calibrate", str(tmp_path / "dusty.npy"), "--layout", layout, "--out", str(tmp_path / "c.json")]) == 0
    assert "lenslets of the white image" in capsys.readouterr().out
