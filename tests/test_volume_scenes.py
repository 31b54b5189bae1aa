"""Non-axisymmetric volumetric flames (lf_flame.simulate.scenes_volume.nonaxisymmetric_flame_scene)."""
import math

import numpy as np
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.simulate.scenes_volume import nonaxisymmetric_flame_scene

CAM = PlenopticCamera(n_rows=41, n_cols=41)                      # a 5.4 mm field
KW = dict(diameter_mm=3.0, n_layers=32, texels_per_lenslet=2.0)


def per_layer(scene, y_sel=None):
    """Each layer's emission integrated over its area (mm^2 x radiance), optionally over rows with y_sel(y) True."""
    out = []
    for layer in scene.layers:
        rows, cols = layer.radiance.shape
        h, w = layer.size_mm
        y = (0.5 - (np.arange(rows) + 0.5) / rows) * h
        keep = np.ones(rows, bool) if y_sel is None else y_sel(y)
        out.append(float(layer.radiance[keep].sum()) * h * w / (rows * cols))
    return np.array(out)


def centroid(scene, y_sel=None):
    e, z = per_layer(scene, y_sel), np.array(scene.objects[0]["layer_depths_mm"])
    return float((e * z).sum() / e.sum())


def test_the_lobe_breaks_the_mirror_symmetry_in_depth():
    plain = nonaxisymmetric_flame_scene(CAM, centre_depth_mm=0.4, tilt_deg=0.0, lobe=(0.0, 0.0, 0.5), **KW)
    e = per_layer(plain)
    assert np.max(np.abs(e - e[::-1])) / e.max() < 0.05                        # no lobe, no tilt: mirror-symmetric
    assert abs(centroid(plain) - 0.4) < 0.01
    for fz in (0.3, -0.3):
        lobed = nonaxisymmetric_flame_scene(CAM, centre_depth_mm=0.4, tilt_deg=0.0, lobe=(2.0, fz, 0.5), **KW)
        e = per_layer(lobed)
        assert np.max(np.abs(e - e[::-1])) / e.max() > 0.15                   # truth != its mirror about the axis
        assert (centroid(lobed) - 0.4) * np.sign(fz) > 0.1                    # the lobe pulls the light its way


def test_the_tilt_moves_the_depth_centroid_with_height():
    for tilt in (12.0, -12.0, 0.0):
        s = nonaxisymmetric_flame_scene(CAM, tilt_deg=tilt, lobe=(0.0, 0.0, 0.5), **KW)
        o = s.objects[0]
        mid = o["base_y_mm"] + o["height_mm"] / 2
        upper = centroid(s, lambda y: (y > mid) & (y < mid + o["height_mm"] / 2))
        lower = centroid(s, lambda y: (y < mid) & (y > mid - o["height_mm"] / 2))
        expect = math.tan(math.radians(tilt)) * o["height_mm"] / 2                # the axis's shift between halves
        assert abs((upper - lower) - expect) < 0.35 * abs(expect) + 0.05, (tilt, upper - lower, expect)
        half = 1.5 + abs(math.tan(math.radians(tilt))) * o["height_mm"] / 2
        np.testing.assert_allclose(o["depth_range_mm"], (-half, half))
        assert o["depth_range_mm"][0] < min(o["layer_depths_mm"]) and max(o["layer_depths_mm"]) < o["depth_range_mm"][1]
        np.testing.assert_allclose(o["layer_thickness_mm"] * 32, 2 * half)
        assert abs(float(sum(layer.radiance for layer in s.layers).max()) - 0.9) < 1e-5


def test_a_seed_reproduces_the_scene():
    a, b, c = (nonaxisymmetric_flame_scene(CAM, np.random.default_rng(s), **KW) for s in (7, 7, 8))
    assert all(np.array_equal(la.radiance, lb.radiance) for la, lb in zip(a.layers, b.layers))
    assert a.objects[0]["tilt_deg"] == b.objects[0]["tilt_deg"] != c.objects[0]["tilt_deg"]
    assert abs(a.objects[0]["tilt_deg"] - 10.0) <= 1.0


@pytest.mark.parametrize("kw, match", [
    (dict(n_layers=1), "n_layers"), (dict(diameter_mm=0.0), "diameter"), (dict(tilt_deg=50.0), "tilt"),
    (dict(height_mm=-1.0), "height"), (dict(lobe=(1.0, 0.7, 0.5)), "lobe"), (dict(lobe=(-1.0, 0.0, 0.5)), "lobe"),
    (dict(lobe=(1.0, 0.0)), "lobe"), (dict(centre_depth_mm=float("nan")), "finite")])
def test_bad_input_is_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        nonaxisymmetric_flame_scene(CAM, **{**dict(diameter_mm=3.0, n_layers=4), **kw})


def test_outside_share_of_the_volume_experiment():
    import importlib.util
    import pathlib
    path = pathlib.Path(__file__).resolve().parents[1] / "experiments" / "volume.py"
    spec = importlib.util.spec_from_file_location("volume_script", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    depths = [-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5]
    truth = np.zeros((7, 4, 4))
    truth[2:5, 1:3, 1:3] = 1.0                                    # the flame spans -0.5..0.5 mm
    x = truth.copy()
    x[0, 1, 1] = 2.0                                              # -1.5 mm: outside (-0.75 - 0.25 pad)
    x[1, 1, 2] = 1.0                                              # -1.0 mm: inside the padded range
    x[6, 2, 2] = -5.0                                             # negative: not emission, left out
    m = mod.metrics(x, truth, depths, (-0.75, 0.75))
    assert m["outside_share"] == pytest.approx(2.0 / (12 + 2 + 1))
    assert m["outside_los_mean"] == pytest.approx((2.0 / 5) / 4)    # one of the 4 lit lines holds 2 of its 5
    base = mod.metrics(x, truth, depths)
    assert "outside_share" not in base and all(base[k] == m[k] for k in base)
