"""The camera's general lenslet grid (rotated, offset, non-integer pitch, hexagonal) and its rendering."""
import dataclasses
import json
import math

import numpy as np
import pytest

from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.refocus.shift_and_sum import raw_to_views


@pytest.fixture(scope="module")
def tiny():
    return PlenopticCamera(n_rows=15, n_cols=17, pixels_per_lenslet=9)


def test_general_kernel_reproduces_the_perfect_grid(tiny):
    """grid_pitch_px = N, no rotation, no offset: the general renderer traces the same rays."""
    general = dataclasses.replace(tiny, grid_pitch_px=9.0)
    assert general.sensor_shape == tiny.sensor_shape
    sc = scenes.shapes_scene(tiny, np.random.default_rng(3))
    a = simulate.render(tiny, sc, 8, 1)
    b = simulate.render(general, sc, 8, 1)
    d = np.abs(a - b)
    assert a.mean() > 0.01
    assert d.mean() < 1e-5 and np.mean(d > 1e-4) < 1e-3, (d.mean(), np.mean(d > 1e-4))


def test_perfect_camera_serialises_as_before_and_general_round_trips(tiny):
    assert not any(k.startswith(("grid_", "sensor_rows", "sensor_cols")) for k in tiny.to_dict())
    g = dataclasses.replace(tiny, grid_pitch_px=10.37, grid_rotation_deg=1.2, grid_offset_px=(0.3, -2.1),
                            grid_layout="hex")
    back = PlenopticCamera.from_dict(json.loads(g.to_json()))
    assert back == g and back.grid_offset_px == (0.3, -2.1)


@pytest.mark.parametrize("kwargs, match", [
    (dict(grid_rotation_deg=1.0), "grid_pitch_px"),
    (dict(grid_pitch_px=8.0), "do not fit under"),
    (dict(grid_pitch_px=1.5, pixels_per_lenslet=1), ">= 2"),
    (dict(grid_pitch_px=12.0, grid_rotation_deg=50.0), "below 45"),
    (dict(grid_pitch_px=12.0, grid_layout="hex", grid_rotation_deg=31.0), "below 30"),
    (dict(grid_pitch_px=12.0, grid_layout="triangle"), "grid_layout"),
    (dict(grid_pitch_px=12.0, grid_offset_px=(float("nan"), 0.0)), "grid_offset_px"),
    (dict(grid_pitch_px=12.0, grid_offset_px=(200.0, 0.0)), "does not fit"),
    (dict(grid_pitch_px=12.0, sensor_rows=100, sensor_cols=100), "does not fit"),
])
def test_impossible_grids_are_refused(tiny, kwargs, match):
    with pytest.raises(ValueError, match=match):
        dataclasses.replace(tiny, **kwargs)


def test_crosstalk_through_a_general_grid_is_refused(tiny):
    g = dataclasses.replace(tiny, grid_pitch_px=9.5)
    sc = scenes.white_scene(g)
    sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, crosstalk=True))
    with pytest.raises(ValueError, match="crosstalk"):
        simulate.render(g, sc, 1)


@pytest.mark.parametrize("layout", ["square", "hex"])
def test_nearest_lenslet_of_each_centre_is_itself(tiny, layout):
    g = dataclasses.replace(tiny, grid_pitch_px=11.3, grid_rotation_deg=-1.7, grid_offset_px=(1.2, 0.4),
                            grid_layout=layout)
    c = g.lenslet_image_centres_px()
    rng = np.random.default_rng(0)
    jitter = rng.uniform(-0.3, 0.3, c.shape) * g.grid_pitch * (0.8 if layout == "square" else 0.7)
    r, k = g.nearest_lenslet((c + jitter).reshape(-1, 2))
    rr, kk = np.meshgrid(np.arange(g.n_rows), np.arange(g.n_cols), indexing="ij")
    assert np.array_equal(r, rr.ravel()) and np.array_equal(k, kk.ravel())
    # neighbouring centres are one pitch apart
    d = np.linalg.norm(np.diff(c, axis=1), axis=-1)
    assert np.allclose(d, 11.3)


@pytest.mark.parametrize("layout, cell", [("square", 1.0), ("hex", math.sqrt(3) / 2)])
def test_white_image_discs_fill_their_cells(layout, cell):
    """Each lenslet images the round main-lens aperture as a disc of diameter D g / d,
    so a white image (no cos⁴) averages disc area / cell area over whole cells."""
    cam = PlenopticCamera(n_rows=12, n_cols=12, pixels_per_lenslet=9, grid_pitch_px=13.47,
                          grid_rotation_deg=1.5, grid_offset_px=(0.7, -0.4), grid_layout=layout)
    disc = cam.aperture_diameter_mm * cam.sensor_distance_mm / cam.mla_distance_mm
    fill = np.pi / 4 * (disc / cam.lenslet_image_pitch_mm) ** 2 / cell
    raw = simulate.render(cam, scenes.white_scene(cam, cos4=False), 16)
    H, W = cam.sensor_shape
    r, c = cam.nearest_lenslet(np.stack(np.mgrid[0:H, 0:W], -1).reshape(-1, 2) + 0.5)
    inner = ((r >= 2) & (r < 10) & (c >= 2) & (c < 10)).reshape(H, W)
    light = raw[inner].sum() / (64 * cell * cam.grid_pitch ** 2)   # per unit cell area
    assert abs(light / fill - 1) < 0.005, (light, fill)
    # and each disc is centred on its lenslet image centre
    cen = cam.lenslet_image_centres_px()[5, 5]
    i, j = np.mgrid[0:H, 0:W] + 0.5
    own = (r == 5).reshape(H, W) & (c == 5).reshape(H, W)
    w = raw * own
    assert np.hypot(np.sum(w * i) / w.sum() - cen[0], np.sum(w * j) / w.sum() - cen[1]) < 0.05


def test_render_views_of_the_perfect_grid_are_the_raw_pixels(tiny):
    g = dataclasses.replace(tiny, grid_pitch_px=9.0)
    sc = scenes.shapes_scene(tiny, np.random.default_rng(5))
    a = raw_to_views(simulate.render(g, sc, 4, 0), 9)
    b = simulate.render_views(g, sc, 4, 0)   # same areas, same rays
    assert b.shape == a.shape and a.mean() > 0.01
    d = np.abs(a - b)
    assert d.mean() < 1e-5 and np.mean(d > 1e-4) < 1e-3


def test_a_hexagonal_cameras_field_spans_its_rows_spacing(tiny):
    """``field_of_view_mm`` of a hexagonal grid: its rows lie sqrt(3)/2 pitches apart, so its height is the extent of
    the lenslet centres' rows (one spacing per row), not a pitch per row; the width, and a square grid's field, as
    before. The paper's flames drawn on it stand inside its lenslets' rows (they stood past the sensor's edge)."""
    hexa = dataclasses.replace(tiny, grid_pitch_px=10.37, grid_layout="hex")
    square = dataclasses.replace(tiny, grid_pitch_px=10.37)
    s = hexa.object_distance_mm(0.0) / hexa.mla_distance_mm
    rows = hexa.lattice_offsets()[..., 0]
    assert hexa.field_of_view_mm(0.0)[0] == pytest.approx((rows.max() - rows.min() + math.sqrt(3) / 2)
                                                          * hexa.mla_pitch_mm * s)
    assert hexa.field_of_view_mm(0.0)[1] == square.field_of_view_mm(0.0)[1] == tiny.n_cols * tiny.mla_pitch_mm * s
    assert square.field_of_view_mm(0.0)[0] == tiny.n_rows * tiny.mla_pitch_mm * s
    half = hexa.field_of_view_mm(0.0)[0] / 2
    for o in scenes.flame_scene(hexa, np.random.default_rng(0), vary=False).objects:
        z = hexa.object_distance_mm(o["depth_offset_mm"]) / hexa.focus_distance_mm
        assert -half * z <= o["base_y_mm"], o
