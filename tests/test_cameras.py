"""Scenes and decoding for any camera: random-depth flames scaled to the camera, white images from
the command line, and the views a lenslet image holds."""
from __future__ import annotations

import json
import types
from pathlib import Path

import numpy as np
import pytest

from lf_flame import cli
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.optics.camera_file import camera_from_datasheet, load_camera_file, load_colour_sensor
from lf_flame.real.view_grid import max_views
from lf_flame.simulate.scenes_depth import DEPTH_RANGE_MM, HEIGHT_RANGE_MM, camera_depth_ranges, camera_depth_scene

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml"
COLOUR_EXAMPLE = EXAMPLE.with_name("colour_camera.toml")
#: 300 µm lenslets of 18.6 mm, 400 mm behind a 200 mm lens, 6.45 µm pixels: 48 views, 19 x 26 lenslets.
DEEP = {"main_lens": {"focal_length_mm": 200.0, "mla_distance_mm": 400.0},
        "microlens_array": {"pitch_um": 300.0, "focal_length_mm": 18.6},
        "sensor": {"pixel_size_um": 6.45, "rows": 960, "cols": 1280}}


def test_the_shipped_colour_camera_is_the_example_camera_with_an_rggb_cfa():
    """The temperature guide's colour camera file: the example camera's optics, its sensor an RGGB mosaic
    (the example camera itself monochrome)."""
    assert load_camera_file(COLOUR_EXAMPLE).to_dict() == load_camera_file(EXAMPLE).to_dict()
    sensor = load_colour_sensor(COLOUR_EXAMPLE)
    assert sensor.pattern == "RGGB" and tuple(sensor.phase) == (0, 0)
    assert load_colour_sensor(EXAMPLE) is None


def test_random_depth_ranges_are_the_papers_on_its_camera():
    r = camera_depth_ranges(PAPER_CAMERA)
    assert r["depth_range"] == pytest.approx(DEPTH_RANGE_MM, abs=1e-3)
    assert r["height_range"] == pytest.approx(HEIGHT_RANGE_MM, rel=1e-4)
    assert r["min_half_width_mm"] == pytest.approx(0.4, rel=1e-4)


@pytest.mark.parametrize("camera", [load_camera_file(EXAMPLE), camera_from_datasheet(DEEP)])
def test_random_depth_scenes_fit_any_camera(camera):
    """Other cameras: the flames' parallax across the aperture is at most the paper camera's share of
    the field (slopes scaled by min(14 / (N - 1), min(R, C) / 90)), within a quarter of the focus
    distance, each flame inside the field and at least 6 lenslet footprints wide."""
    n, R, C = camera.pixels_per_lenslet, camera.n_rows, camera.n_cols
    lo, hi = camera_depth_ranges(camera)["depth_range"]
    scale = min(14 / (n - 1), min(R, C) / 90)
    assert camera.slope_for_depth(lo) >= -1.91 * scale and camera.slope_for_depth(hi) <= 2.82 * scale
    assert -lo <= 0.25 * camera.focus_distance_mm + 1e-9 and hi <= 0.25 * camera.focus_distance_mm + 1e-9
    foot = camera.mla_pitch_mm * camera.focus_distance_mm / camera.mla_distance_mm
    for seed in range(4):
        sc = camera_depth_scene(camera, np.random.default_rng(seed))
        assert 1 <= len(sc.objects) <= 4
        for o in sc.objects:
            assert lo <= o["depth_offset_mm"] <= hi
            fh, fw = camera.field_of_view_mm(o["depth_offset_mm"])
            assert o["height_mm"] <= 0.85 * fh and abs(o["centre_x_mm"]) <= 0.45 * fw
            assert o["half_width_mm"] >= 3.0 * foot - 1e-6


def test_a_lenslet_image_holds_its_whole_views():
    """A calibrated pitch a hair below a whole number keeps that number of views (15 for 14.9997),
    a fractional one its floor."""
    assert max_views(types.SimpleNamespace(pitch_px=14.9997)) == 15
    assert max_views(types.SimpleNamespace(pitch_px=15.0)) == 15
    assert max_views(types.SimpleNamespace(pitch_px=10.57)) == 10
    assert max_views(types.SimpleNamespace(pitch_px=48.67)) == 48


def test_simulate_white_and_random_depth_scenes_of_a_camera_file(tmp_path, capsys):
    """``simulate --scene white`` and ``--scene depth`` render any camera file, and the stored scene
    is the one rebuilt from its record (what reconstruct scores against)."""
    from lf_flame.cli._io import _raw_scene
    cam = load_camera_file(EXAMPLE)
    for scene in ("white", "depth"):
        out = tmp_path / f"{scene}.npz"
        assert cli.main(["simulate", "--scene", scene, "--camera", str(EXAMPLE), "--rays-per-pixel", "1",
                         "--seed", "3", "--out", str(out)]) == 0
        z = np.load(out)
        assert z["raw"].shape == cam.sensor_shape
        assert json.loads(str(z["objects"])) == json.loads(json.dumps(_raw_scene(out, cam).objects, default=float))
    lo, hi = camera_depth_ranges(cam)["depth_range"]
    assert all(lo <= o["depth_offset_mm"] <= hi for o in json.loads(str(np.load(tmp_path / "depth.npz")["objects"])))
    white = np.load(tmp_path / "white.npz")["raw"]
    assert white.mean() > 0.2            # a flat field lights every lenslet image


def test_simulate_refuses_a_bit_depth_out_of_range(tmp_path, capsys):
    for bits in ("0", "33", "x"):
        with pytest.raises(SystemExit) as e:
            cli.main(["simulate", "--scene", "point", "--bit-depth", bits, "--out", str(tmp_path / "p.npz")])
        assert e.value.code == 2
    assert "--bit-depth takes an integer from 1 to 32" in capsys.readouterr().err
