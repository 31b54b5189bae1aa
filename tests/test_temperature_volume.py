"""Two-colour temperature per voxel of an axisymmetric colour flame, on a small camera."""
import dataclasses

import numpy as np
import pytest

from lf_flame.temperature import pyrometry as P
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.optics.colour import band_integrals, library_sensor, mosaic
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate import tracer
from lf_flame.simulate.scenes_temperature import blackbody_channels, colour_flame_scene
from lf_flame.simulate.scenes_volume_temperature import (axisymmetric_node_truth, axisymmetric_temperature_field,
                                                         colour_axisymmetric_scene)
from lf_flame.temperature.axisymmetric import axisymmetric_temperature, volume_temperature
from lf_flame.temperature.mosaic import channel_views
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.truth import scene_truth

CAM = PlenopticCamera(n_rows=41, n_cols=41)
GAINS = (1.0, 1.25, 0.8)
SENSOR = library_sensor(gains=GAINS)
MODEL = library_sensor()
W = CAM.field_of_view_mm(0.0)[1]
KW = dict(diameter_mm=0.5 * W, centre_x_mm=0.05 * W, centre_depth_mm=0.5, core=0.3, peak_k=2050.0)
DEPTHS = list(np.arange(-3.0, 3.01, 0.5))
#: tolerances (K) over the bright voxels and nodes, noise-free, 32 rays per pixel (measured with the matched
#: route: voxels 14 / 62 K, nodes 35 / 76 K; each channel on its own samples: voxels 24 / 106 K)
MEDIAN_K, P90_K = 40.0, 80.0


def _cal():
    t = (1500.0, 2000.0, 2500.0)
    return P.fit_calibration(MODEL, t, [blackbody_channels(SENSOR, x)[0] / blackbody_channels(SENSOR, x)[1]
                                        for x in t])


def _channel(cs, c):
    return dataclasses.replace(cs.scene, layers=tuple(dataclasses.replace(L, radiance=cs.channel_radiance[k][c])
                                                      for k, L in enumerate(cs.scene.layers)))


@pytest.fixture(scope="module")
def case():
    cs = colour_axisymmetric_scene(CAM, SENSOR, None, n_layers=16, **KW)
    raw = mosaic(np.stack([tracer.render(CAM, _channel(cs, c), 32, 0, sensor=False) for c in range(3)]), SENSOR)
    views = raw_to_views(raw, CAM.pixels_per_lenslet)
    chan = channel_views(raw.shape, SENSOR, CAM.pixels_per_lenslet)
    op = ExactOperator(CAM, DEPTHS, precision="float32")
    cal = _cal()
    tr = [scene_truth(_channel(cs, c), op) for c in (0, 1)]
    Tt, _, _ = volume_temperature(tr[0], tr[1], cal, MODEL, min_fraction=0.0)
    vt = (tr[0] + tr[1]) >= 0.1 * (tr[0] + tr[1]).max()
    res = axisymmetric_temperature(views, op, chan, cal, MODEL, camera=CAM)
    return dict(cs=cs, views=views, chan=chan, op=op, cal=cal, Tt=Tt, vt=vt, res=res)


def _errors(T, valid, Tt, vt):
    e = np.abs(T - Tt)[vt & valid]
    return float(np.median(e)), float(np.percentile(e, 90)), float((vt & ~valid).sum() / vt.sum())


def test_temperature_field_hottest_on_sheath():
    cs = colour_axisymmetric_scene(CAM, SENSOR, None, n_layers=4, **KW)
    o = cs.scene.objects[0]
    y = o["base_y_mm"] + 0.3 * o["height_mm"]
    R = 0.4 * o["diameter_mm"] * np.sqrt(0.7)
    r = np.linspace(0, 2 * R, 201)
    T = axisymmetric_temperature_field(r, y, o, 2050.0)
    assert abs(r[np.argmax(T)] - R) <= 0.02 * R and T.max() > T[0] + 150 and T.max() > T[-1] + 150
    hi = axisymmetric_temperature_field(R, o["base_y_mm"] + 0.9 * o["height_mm"], o, 2050.0)
    assert hi < T.max() - 100                                            # cooler up the flame
    # a layer's channels follow the band-integral law at its texels' temperature
    k = int(np.argmax([s.max() for s in cs.soot]))
    i = np.unravel_index(np.argmax(cs.soot[k]), cs.soot[k].shape)
    s = band_integrals(SENSOR, cs.temperature_k[k][i], gains=True)
    got = cs.channel_radiance[k][:, i[0], i[1]]
    assert np.allclose(got / got[1], s / s[1], rtol=1e-4)


def test_voxel_temperature_noise_free(case):
    res, o = case["res"], case["cs"].scene.objects[0]
    assert abs(res.axis_x_mm - o["centre_x_mm"]) < 0.05 and abs(res.axis_z_mm - o["depth_offset_mm"]) < 0.3
    med, p90, masked = _errors(res.temperature_volume, res.valid_volume, case["Tt"], case["vt"])
    print(f"voxels: median {med:.1f} K, p90 {p90:.1f} K, masked {masked:.3f}")
    assert med <= MEDIAN_K and p90 <= P90_K and masked <= 0.25
    Tn, en = axisymmetric_node_truth(case["cs"], SENSOR, res.radii_mm, res.heights_mm)
    bn = (en[0] + en[1]) >= 0.1 * (en[0] + en[1]).max()
    med_n, p90_n, masked_n = _errors(res.temperature, res.valid, Tn, bn)
    print(f"nodes: median {med_n:.1f} K, p90 {p90_n:.1f} K, masked {masked_n:.3f}")
    assert med_n <= MEDIAN_K and p90_n <= P90_K and masked_n <= 0.25


def test_matching_the_channels_beats_each_on_its_own_samples(case):
    """The default (matched) route against each channel solved on its own samples alone, on the
    same axis: the voxels' p90 drops (measured 106 -> 62 K on this scene, 32 rays)."""
    res = case["res"]
    own = res.own_samples
    p90 = [_errors(x.temperature_volume, x.valid_volume, case["Tt"], case["vt"])[1] for x in (res, own)]
    print(f"voxels' p90: matched {p90[0]:.1f} K, own samples {p90[1]:.1f} K")
    assert p90[0] < 0.8 * p90[1]


def test_swapped_channel_mask_breaks_it(case):
    res, chan = case["res"], case["chan"]
    swapped = chan.copy()
    swapped[chan == 0], swapped[chan == 1] = 1, 0
    bad = axisymmetric_temperature(case["views"], case["op"], swapped, case["cal"], MODEL, axis_x_mm=res.axis_x_mm,
                                   axis_z_mm=res.axis_z_mm, r_max_mm=float(res.radii_mm[-1]),
                                   dr_mm=float(res.radii_mm[1]))
    med, p90, masked = _errors(bad.temperature_volume, bad.valid_volume, case["Tt"], case["vt"])
    print(f"swapped: median {med:.1f} K, p90 {p90:.1f} K, masked {masked:.3f}")
    assert med > 3 * MEDIAN_K or masked > 0.5


def test_refusals(case):
    res, views, chan, op, cal = case["res"], case["views"], case["chan"], case["op"], case["cal"]
    with pytest.raises(ValueError, match="channel map"):
        axisymmetric_temperature(views, op, chan[..., :-1], cal, MODEL)
    with pytest.raises(ValueError, match="calibration"):
        axisymmetric_temperature(views, op, chan, cal, library_sensor(phase=(1, 1)))
    with pytest.raises(ValueError, match="both"):
        axisymmetric_temperature(views, op, chan, cal, MODEL, axis_x_mm=res.axis_x_mm)
    with pytest.raises(ValueError, match="no unsaturated"):
        axisymmetric_temperature(views, op, chan, cal, MODEL, saturation=0.0)
    with pytest.raises(ValueError, match="one shape"):
        volume_temperature(np.ones(3), np.ones(4), cal, MODEL)
    with pytest.raises(ValueError, match="no positive"):
        volume_temperature(np.zeros(3), np.zeros(3), cal, MODEL)
    with pytest.raises(ValueError, match="peak"):
        colour_axisymmetric_scene(CAM, SENSOR, n_layers=2, peak=1.5)
    with pytest.raises(ValueError, match="base_k"):
        colour_axisymmetric_scene(CAM, SENSOR, n_layers=2, peak_k=1400.0)
    with pytest.raises(ValueError, match="r_mm"):
        axisymmetric_temperature_field(-1.0, 0.0, case["cs"].scene.objects[0], 2000.0)
    with pytest.raises(ValueError, match="colour_axisymmetric"):
        axisymmetric_node_truth(colour_flame_scene(CAM, SENSOR), SENSOR, [0.0, 0.1], [0.0])
