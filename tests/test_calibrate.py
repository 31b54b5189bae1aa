"""Lenslet-grid calibration from a white image and decoding to views, against the simulator's truth."""
import dataclasses
import json

import numpy as np
import pytest

from lf_flame.real import calibration as calibrate
from lf_flame import cli
from lf_flame.real import decoding as decode
from lf_flame.real.views_file import load_views
from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.real.calibration import CalibrationError, GridCalibration
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.refocus.shift_and_sum import aperture_mask
from lf_flame.refocus.slope_search import find_sharpest_slope


def _camera(layout="square", rotation=1.3):
    return PlenopticCamera(n_rows=16, n_cols=18, pixels_per_lenslet=25, grid_pitch_px=27.47,
                           grid_rotation_deg=rotation, grid_offset_px=(3.2, -5.7), grid_layout=layout)


@pytest.fixture(scope="module", params=[("square", 1.3), ("square", -1.9), ("hex", 0.7)], ids=str)
def white_case(request):
    cam = _camera(*request.param)
    white = simulate.render(cam, scenes.white_scene(cam), 16)
    return cam, white, calibrate.calibrate(white)


@pytest.fixture(scope="module")
def square_lf():
    cam = _camera()
    white_scene = scenes.white_scene(cam)
    scene = scenes.shapes_scene(cam, np.random.default_rng(1))
    white = simulate.render(cam, white_scene, 64)
    return cam, scene, white_scene, white, simulate.render(cam, scene, 64, 1), calibrate.calibrate(white)


def _nearest(points, truth):
    d = np.hypot(points[:, None, 0] - truth[None, :, 0], points[:, None, 1] - truth[None, :, 1])
    return d.min(axis=1), d.argmin(axis=1)


def test_calibration_recovers_the_rendered_grid(white_case):
    cam, white, cal = white_case
    assert cal.layout == cam.grid_layout
    assert abs(cal.pitch_px / cam.grid_pitch_px - 1) < 5e-4, cal.pitch_px
    assert abs(cal.rotation_deg - cam.grid_rotation_deg) < 0.02, cal.rotation_deg
    truth = cam.lenslet_image_centres_px().reshape(-1, 2)
    err, _ = _nearest(cal.centres_px().reshape(-1, 2), truth)
    assert err.max() < 0.1, err.max()
    err, _ = _nearest(cal.lenslets[:, 2:], truth)        # each measured centre, too
    assert err.max() < 0.5 and np.sqrt(np.mean(err ** 2)) < 0.2
    assert cal.residual_rms_px < 0.2
    # every lenslet whose image is whole on the sensor is decoded, and only those
    assert cal.n_rows * cal.n_cols >= 0.7 * cam.n_rows * cam.n_cols
    # the same grid at any exposure (a white image x1e-9 had been refused as constant against an absolute floor)
    for scale in (1e-12, 1e12):
        again = calibrate.calibrate(white * scale)
        assert abs(again.pitch_px - cal.pitch_px) < 1e-6 * cal.pitch_px and again.n_rows == cal.n_rows


def test_decoded_views_match_the_directly_rendered_views(square_lf):
    """Measured (64 rays per pixel): RMSE 0.0144 of white-normalised radiance (signal RMS 0.238),
    where two direct renders with other seeds differ by 0.0100 (Monte Carlo noise)."""
    cam, scene, white_scene, white, raw, cal = square_lf
    views = decode.decode(raw, cal, white, n_views=25)
    _, k = _nearest(cal.centres_px()[:1, 0], cam.lenslet_image_centres_px().reshape(-1, 2))
    r0, c0 = divmod(int(k[0]), cam.n_cols)
    R, C = views.shape[2:]
    sl = (slice(None), slice(None), slice(r0, r0 + R), slice(c0, c0 + C))
    ref = simulate.render_views(cam, scene, 64, 2)[sl]
    ref_white = simulate.render_views(cam, white_scene, 64, 3)[sl]
    lit = ref_white > 0.5 * ref_white.max()
    ref = np.where(lit, ref / np.where(lit, ref_white, 1), 0)
    rmse = np.sqrt(np.mean((views - ref)[lit] ** 2))
    assert rmse < 0.02, rmse
    assert np.sqrt(np.mean(ref[lit] ** 2)) > 0.2
    # the slope search on the decoded views finds each object's analytic slope
    for o in scene.objects:
        r_0, r_1, c_0, c_1 = o["roi"]
        roi = (max(0, r_0 - r0), min(R, r_1 - r0), max(0, c_0 - c0), min(C, c_1 - c0))
        s = find_sharpest_slope(views, roi, mask=aperture_mask(25, "circular"))
        assert abs(s.slope - cam.slope_for_depth(o["depth_offset_mm"])) < 0.03, (o["name"], s.slope)


def test_hexagonal_views_are_resampled_to_a_square_grid(white_case):
    cam, white, cal = white_case
    views = decode.decode(white, cal, white, n_views=21)
    if cal.layout == "square":
        assert views.shape == (21, 21, cal.n_rows, cal.n_cols)
    else:
        assert views.shape == (21, 21, int(np.floor((cal.n_rows - 1) * np.sqrt(3) / 2)) + 1, cal.n_cols - 1)
    centre = views[8:13, 8:13]                      # white / white inside the lenslet images: 1
    assert np.allclose(centre, 1.0, atol=1e-3)


def test_calibration_file_round_trip_and_corruption(white_case, tmp_path):
    cal = white_case[2]
    p = cal.save(tmp_path / "c.json")
    back = GridCalibration.load(p)
    assert back.pitch_px == pytest.approx(cal.pitch_px) and np.allclose(back.centres_px(), cal.centres_px())
    d = json.loads(p.read_text())
    for change, match in ((dict(format="other"), "not an lf_flame"), (dict(version=9), "version"),
                          (dict(pitch_px=float("nan")), "non-finite"), (dict(layout="tri"), "layout"),
                          (dict(origin_px=[1e6, 0]), "off its sensor")):
        (tmp_path / "bad.json").write_text(json.dumps({**d, **change}))
        with pytest.raises(ValueError, match=match):
            GridCalibration.load(tmp_path / "bad.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        GridCalibration.load(tmp_path / "bad.json")


# ---- bad input ----------------------------------------------------------------------------
def test_white_image_without_a_grid_is_refused(square_lf):
    rng = np.random.default_rng(0)
    with pytest.raises(CalibrationError, match="no lenslet grid found"):
        calibrate.calibrate(rng.random((300, 320)))
    with pytest.raises(CalibrationError, match="not a white image: it is constant"):
        calibrate.calibrate(np.full((300, 320), 0.7))
    with pytest.raises(CalibrationError, match="over-exposed"):
        calibrate.calibrate(np.clip(square_lf[3] * 4, 0, 1))        # 4x the exposure: clipped


def test_dark_frame_only_is_not_a_white_image(white_case):
    cam, white, _ = white_case
    with pytest.raises(CalibrationError):
        calibrate.calibrate(white, dark=white)


def test_image_lit_on_one_side_is_not_a_white_image(square_lf):
    """Light falling off steeply across the field (a misplaced diffuser): the lattice is
    there, but most lenslet images are too dark to calibrate."""
    white = square_lf[3]
    ramp = np.linspace(0, 1, white.shape[1]) ** 8
    with pytest.raises(CalibrationError, match="not a white image: only"):
        calibrate.calibrate(white * ramp)


def test_nan_is_refused(square_lf):
    cam, _, _, white, raw, cal = square_lf
    bad = white.copy()
    bad[10, 10] = np.nan
    with pytest.raises(ValueError, match="white image contains NaN"):
        calibrate.calibrate(bad)
    with pytest.raises(ValueError, match="raw image contains NaN"):
        decode.decode(np.where(np.arange(raw.size).reshape(raw.shape) == 7, np.nan, raw), cal, white)
    with pytest.raises(ValueError, match="dark frame contains NaN"):
        decode.decode(raw, cal, white, np.full(raw.shape, np.inf))


def test_raw_of_another_size_is_refused(square_lf):
    cam, _, _, white, raw, cal = square_lf
    with pytest.raises(ValueError, match=r"raw image has shape \(451, 500\), not the \(451, 504\)"):
        decode.decode(raw[:, :500], cal, white)
    with pytest.raises(ValueError, match="white image has shape"):
        decode.decode(raw, cal, white[:-1])


def test_calibration_of_another_camera_is_refused(square_lf):
    cam, _, _, white, raw, cal = square_lf
    H, W = raw.shape
    other = dataclasses.replace(cam, grid_pitch_px=22.3, pixels_per_lenslet=21, n_rows=19, n_cols=21,
                                sensor_rows=H, sensor_cols=W)        # same sensor size, another MLA
    other_raw = simulate.render(other, scenes.shapes_scene(other, np.random.default_rng(1)), 4)
    with pytest.raises(ValueError, match="another camera"):
        decode.decode(other_raw, cal, white)
    decode.check_grid(raw, cal)  # its own camera passes
    with pytest.raises(ValueError, match="of camera 'A', not 'B'"):
        decode.decode(raw, dataclasses.replace(cal, camera_id="A"), white, camera_id="B")


# ---- the command line ------------------------------------------------------------------------
def test_cli_calibrate_decode_refocus_slopes(square_lf, tmp_path, capsys):
    cam, scene, _, white, raw, cal = square_lf
    np.save(tmp_path / "white.npy", white)
    np.save(tmp_path / "raw.npy", raw)
    dark = np.zeros_like(white)
    np.save(tmp_path / "dark.npy", dark)
    assert cli.main(["calibrate", str(tmp_path / "white.npy"), "--dark", str(tmp_path / "dark.npy"),
                     "--camera-id", "sim", "--out", str(tmp_path / "c.json")]) == 0
    got = GridCalibration.load(tmp_path / "c.json")
    assert got.pitch_px == pytest.approx(cal.pitch_px) and got.white["sha256"] and got.camera_id == "sim"
    assert cli.main(["decode", str(tmp_path / "raw.npy"), "--calibration", str(tmp_path / "c.json"),
                     "--views", "25", "--out", str(tmp_path / "v.h5")]) == 0
    views, _ = load_views(tmp_path / "v.h5")
    assert np.allclose(views, decode.decode(raw, cal, white, dark, n_views=25), atol=1e-5)
    assert cli.main(["refocus", str(tmp_path / "v.h5"), "--slope", "0", "--slope", "1.25",
                     "--out", str(tmp_path / "s.npz")]) == 0
    with np.load(tmp_path / "s.npz") as z:
        assert z["stack"].shape == (2,) + views.shape[2:]
    assert cli.main(["slopes", str(tmp_path / "v.h5"), "--roi", "0", "8", "0", "9",
                     "--out-prefix", str(tmp_path / "sl")]) == 0
    assert (tmp_path / "sl.slopes.csv").exists()
    # bad input through the CLI: a clear error, exit status 2
    np.save(tmp_path / "small.npy", raw[:-3])
    assert cli.main(["decode", str(tmp_path / "small.npy"), "--calibration", str(tmp_path / "c.json"),
                     "--out", str(tmp_path / "x.h5")]) == 2
    assert "raw image has shape" in capsys.readouterr().err
    np.save(tmp_path / "white.npy", white * 0.5)                       # the white image changed
    assert cli.main(["decode", str(tmp_path / "raw.npy"), "--calibration", str(tmp_path / "c.json"),
                     "--out", str(tmp_path / "x.h5")]) == 2
    assert "has changed since the calibration" in capsys.readouterr().err
