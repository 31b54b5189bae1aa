"""Colour sensor, colour renders and two-colour pyrometry, on a small camera."""
import json

import numpy as np
import pytest
from scipy.special import gamma, gammainc

from lf_flame.temperature import pyrometry as P
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.optics.colour import (DEFAULT_SENSITIVITIES, LAMBDA0_NM, ColourSensor, band_integrals, cfa_channels,
                                    library_sensor, planck_radiance)
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate import tracer
from lf_flame.simulate.colour import render_colour
from lf_flame.simulate.layers import Effects, Layer, Scene
from lf_flame.simulate.scenes_temperature import furnace_scene
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.solvers import reconstruct

CAM = PlenopticCamera(n_rows=21, n_cols=21)
GAINS = (1.0, 1.3, 0.7)


def test_cfa_phase():
    ch = cfa_channels((4, 4), "RGGB", (0, 0))
    assert ch[0, 0] == 0 and ch[0, 1] == 1 and ch[1, 0] == 1 and ch[1, 1] == 2 and ch[2, 2] == 0
    assert cfa_channels((2, 2), "RGGB", (1, 1))[0, 0] == 2
    # phase is (row, col): (1, 0) puts pixel (0, 1) on B, (0, 1) puts it on R
    assert cfa_channels((2, 2), "RGGB", (1, 0))[0, 1] == 2
    assert cfa_channels((2, 2), "RGGB", (0, 1))[0, 1] == 0
    # a render of red light alone lights only the red pixels (rows and columns even)
    sensor = library_sensor(phase=(0, 0))
    scene, ch3 = furnace_scene(CAM, sensor, 2000.0)
    ch3 = [np.stack([ch3[0][0], 0 * ch3[0][1], 0 * ch3[0][2]])]
    raw = render_colour(CAM, scene, ch3, sensor, 2, 0)
    lit = raw > 0
    assert lit[0::2, 0::2].any() and not lit[1::2, :].any() and not lit[:, 1::2].any()
    with pytest.raises(ValueError, match="phase"):
        cfa_channels((2, 2), "RGGB", (2, 0))


def _closed_form(l1_nm, l2_nm, t, alpha, terms=6):
    """∫ (λ/λ0)^-α (c1/π) λ^-5 / (exp(c2/λT) - 1) dλ over [l1, l2] (m), by x = c2/(λT) and
    1/(e^x - 1) = Σ e^{-nx}: each term a regularised incomplete gamma function."""
    c1, c2 = 3.741771e-16, 0.014388      # colour-science's planck_law constants
    s = 4.0 + alpha
    a, b = c2 / (l2_nm * 1e-9 * t), c2 / (l1_nm * 1e-9 * t)
    series = sum(n ** -s * gamma(s) * (gammainc(s, n * b) - gammainc(s, n * a)) for n in range(1, terms + 1))
    return c1 / np.pi * (LAMBDA0_NM * 1e-9) ** alpha * (t / c2) ** s * series


def test_library_sensitivities_are_read_once_and_kept_in_the_cache(tmp_path, monkeypatch):
    """library_sensor reads colour-science's curves once per name and version and keeps them in the cache: a process
    that cannot import colour-science then gets the same sensor; a cache file that cannot be read is read again and
    replaced; an unknown name is refused."""
    import os
    import subprocess
    import sys

    import colour
    monkeypatch.setenv("LF_FLAME_CACHE", str(tmp_path))
    want = colour.MSDS_CAMERA_SENSITIVITIES[DEFAULT_SENSITIVITIES]
    s = library_sensor()
    np.testing.assert_array_equal(s.wavelengths_nm, want.wavelengths)
    np.testing.assert_array_equal(s.sensitivities, np.clip(want.values, 0, None))
    (cached,) = tmp_path.iterdir()
    code = ("import sys; sys.modules['colour'] = None; import numpy as np; from lf_flame.optics.colour import "
            "library_sensor; np.save(sys.argv[1], library_sensor().sensitivities)")
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "got.npy")], check=True,
                   env={**os.environ, "LF_FLAME_CACHE": str(tmp_path)})
    np.testing.assert_array_equal(np.load(tmp_path / "got.npy"), s.sensitivities)
    cached.write_bytes(b"not a zip file")
    np.testing.assert_array_equal(library_sensor().sensitivities, s.sensitivities)
    with np.load(cached) as f:
        assert str(f["name"]) == DEFAULT_SENSITIVITIES
    with pytest.raises(ValueError, match="no camera sensitivities named"):
        library_sensor("no such camera")


def test_planck_radiance_is_colour_sciences_planck_law():
    """Planck's law as written here (no colour-science import) is colour-science's ``planck_law`` to rounding, every
    temperature of an array at every wavelength."""
    from colour.colorimetry import planck_law
    wl = np.arange(380.0, 781.0, 5.0)
    t = np.array([[300.0, 1500.0], [2000.0, 3000.0]])
    got = planck_radiance(wl, t)
    want = np.asarray(planck_law(wl * 1e-9, t.ravel())).T.reshape(t.shape + wl.shape)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert planck_radiance(wl, 2000.0).shape == wl.shape


@pytest.mark.parametrize("alpha", [0.0, 1.39])
@pytest.mark.parametrize("t", [1500.0, 2500.0])
def test_band_integration_against_closed_form(alpha, t):
    wl = np.arange(500.0, 601.0, 1.0)                       # a flat band 500-600 nm in every channel
    flat = ColourSensor("flat", "RGGB", (0, 0), wl, np.ones((len(wl), 3)))
    got = band_integrals(flat, t, alpha)
    want = _closed_form(500.0, 600.0, t, alpha)
    np.testing.assert_allclose(got, want, rtol=1e-4)


def _scene(fx):
    r = np.zeros((30, 30), np.float32)
    r[8:22, 10:20] = 0.7
    h, w = CAM.field_of_view_mm(0.0)
    return Scene("blob", (Layer(r, None, 0.0, (0.0, 0.0), (h, w)),), fx)


def test_monochrome_unchanged_and_colour_of_equal_channels_is_monochrome():
    fx = Effects(aperture=True, cos4=True, occlusion=False, full_well_e=500.0, read_noise_e=2.0, bit_depth=12)
    scene = _scene(fx)
    mono = tracer.render(CAM, scene, 4, 3)
    # the default path is the noise-free render with the sensor applied, bit for bit
    assert np.array_equal(mono, tracer.apply_sensor(tracer.render(CAM, scene, 4, 3, sensor=False), fx, 3))
    # three equal channels: the colour render is the monochrome one, noise included
    sensor = library_sensor()
    col = render_colour(CAM, scene, [np.stack([scene.layers[0].radiance] * 3)], sensor, 4, 3)
    assert np.array_equal(col, mono)


def _calibrate(sensor, model, temps=(1400.0, 1800.0, 2200.0, 2600.0)):
    ratios = []
    for t in temps:
        sc, ch = furnace_scene(CAM, sensor, t)
        ratios.append(P.blackbody_ratio(render_colour(CAM, sc, ch, sensor, 2, 1), model, CAM.pixels_per_lenslet))
    return P.fit_calibration(model, temps, ratios)


def test_calibration_round_trip(tmp_path):
    sensor, model = library_sensor(gains=GAINS), library_sensor()
    cal = _calibrate(sensor, model)
    assert cal.gain_ratio == pytest.approx(GAINS[0] / GAINS[1], rel=1e-3)
    path = P.write_calibration(tmp_path / "bb.json", cal)
    assert [p.name for p in tmp_path.iterdir()] == ["bb.json"]      # no temporary file left
    back = P.load_calibration(path, model)
    assert back == cal
    for t in (1550.0, 1950.0, 2450.0):                                # not fitted
        sc, ch = furnace_scene(CAM, sensor, t)
        r = P.blackbody_ratio(render_colour(CAM, sc, ch, sensor, 2, 5), model, CAM.pixels_per_lenslet)
        assert abs(float(P.ratio_to_temperature(r, back, model, alpha=0.0)) - t) < 5.0


def test_wrong_calibration_refused(tmp_path):
    nikon = library_sensor()
    cal = P.fit_calibration(nikon, [2000.0], [float(P.model_ratio(nikon, 2000.0, alpha=0.0))])
    path = P.write_calibration(tmp_path / "bb.json", cal)
    with pytest.raises(ValueError, match="made for sensor"):
        P.load_calibration(path, library_sensor("Sigma SDMerill (NPL)"))
    with pytest.raises(ValueError, match="phase"):
        P.load_calibration(path, library_sensor(phase=(1, 1)))
    # the same layout spelt another way (RGGB from its tile's second column is GRBG): the same sensor
    assert P.load_calibration(path, library_sensor(pattern="GRBG", phase=(0, 1))).pattern == "RGGB"
    with pytest.raises(ValueError, match="phase"):
        P.load_calibration(path, library_sensor(pattern="GRBG", phase=(0, 0)))
    # channels whose ratio does not change with T: no unique temperature
    grey = ColourSensor(nikon.name, "RGGB", (0, 0), nikon.wavelengths_nm, nikon.sensitivities[:, [1, 1, 2]])
    with pytest.raises(ValueError, match="not strictly monotonic"):
        P.ratio_to_temperature(1.0, cal, grey)
    d = json.loads(path.read_text())
    d["kind"] = "something else"
    (tmp_path / "other.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="not an lf_flame temperature calibration"):
        P.load_calibration(tmp_path / "other.json")


def test_blackbodies_the_pyrometer_cannot_check_are_refused():
    """Blackbodies outside the 1000-3200 K the lookup reads are refused naming the range (they gave residuals of
    NaN, written into the calibration's JSON, and a wrong gain ratio without a word); one image given for two
    temperatures (a ratio that does not move) is refused as such, where the direction check had said it 'rises'."""
    nikon = library_sensor()

    def ratios(temps):
        return [1.1 * float(P.model_ratio(nikon, t, alpha=0.0)) for t in temps]
    for temps in ((4500.0, 9000.0), (600.0, 1600.0)):
        with pytest.raises(ValueError, match="outside the 1000-3200 K this pyrometer reads"):
            P.fit_calibration(nikon, temps, ratios(temps))
    same = ratios([1600.0]) * 2
    with pytest.raises(ValueError, match="barely moves.*the same image given for two temperatures"):
        P.fit_calibration(nikon, [1600.0, 2400.0], same)
    cal = P.fit_calibration(nikon, [1600.0, 2400.0], ratios([1600.0, 2400.0]))
    assert cal.gain_ratio == pytest.approx(1.1) and max(map(abs, cal.fit_residuals_k)) < 1e-6
    # images inside the range that the fitted gain reads outside it (NaN residuals, which had been written and the
    # calibration refused only when read as 'malformed')
    off = ratios([1600.0, 2000.0, 2400.0])
    off[2] *= 1e-3
    with pytest.raises(ValueError, match="after the fit the blackbodies at .*2400 K read outside the 1000-3200 K"):
        P.fit_calibration(nikon, [1600.0, 2000.0, 2400.0], off)


def test_temperature_recovered_on_a_planted_plane():
    """A hot rectangle (1900 K) beside a cooler one (1750 K) on the focal plane, in colour,
    reconstructed per channel from its own pixels (CFA mask) by admm: both temperatures back
    within 25 K (the masked reconstructions' ratio is biased by about 1 %, +10-15 K here:
    results/temperature.md)."""
    sensor, model = library_sensor(gains=GAINS), library_sensor()
    cal = P.TemperatureCalibration(model.name, "RGGB", (0, 0), ("R", "G"), GAINS[0] / GAINS[1], (), ())
    soot = np.zeros((42, 42))
    temp = np.full((42, 42), 1750.0)
    soot[10:32, 8:18] = 1.0
    soot[10:32, 24:34] = 1.0
    temp[:, 21:] = 1900.0
    ch = soot[None] * np.moveaxis(band_integrals(sensor, temp, gains=True), -1, 0)
    ch = (ch * 0.8 / ch.max()).astype(np.float32)
    h, w = CAM.field_of_view_mm(0.0)
    scene = Scene("planted", (Layer(ch[1], None, 0.0, (0.0, 0.0), (h, w)),), Effects(occlusion=False))
    raw = render_colour(CAM, scene, [ch], sensor, 16, 2)
    views = raw_to_views(raw, CAM.pixels_per_lenslet)
    chan = raw_to_views(sensor.channel_map(raw.shape).astype(np.float32), CAM.pixels_per_lenslet).astype(int)
    op = ExactOperator(CAM, [0.0])
    rec = [reconstruct(views, op, "admm", 25, saturation=chan != c).planes.reshape(op.dims) for c in (0, 1)]
    t, valid, _ = P.temperature_planes(rec[0], rec[1], cal, model)
    left, right = t[0][5:16, 5:8], t[0][5:16, 13:16]          # lenslets inside each rectangle
    assert np.nanmedian(left) == pytest.approx(1750.0, abs=25.0)
    assert np.nanmedian(right) == pytest.approx(1900.0, abs=25.0)
    assert valid[0].sum() < valid[0].size                       # the dark background is masked


def test_temperature_planes_refuse_nan_and_find_no_bright_pixel_on_an_empty_plane():
    """One NaN pixel in a channel's emission is refused, naming the stack and the plane (it had left its whole plane
    without a temperature, 0 valid and 0 masked, unreported); a plane with no light has no bright pixel (an all-zero
    plane's 100 px had all been reported as bright pixels masked), beside a lit plane whose pixels all get one."""
    model = library_sensor()
    cal = P.TemperatureCalibration(model.name, "RGGB", (0, 0), ("R", "G"), 1.3, (), ())
    a = np.random.default_rng(0).uniform(0.5, 1.0, (2, 10, 10))
    b = a / 1.6
    t, valid, n_masked = P.temperature_planes(a, b, cal, model)
    assert valid.all() and np.all(n_masked == 0)
    for k, bad in ((0, np.nan), (1, np.inf)):
        hole = a.copy()
        hole[k, 3, 4] = bad
        with pytest.raises(ValueError, match=rf"emission_a holds NaN or inf in plane {k} \(1 px\)"):
            P.temperature_planes(hole, b, cal, model)
        with pytest.raises(ValueError, match=rf"emission_b holds NaN or inf in plane {k} \(1 px\)"):
            P.temperature_planes(b, hole, cal, model)
    a[1], b[1] = 0.0, 0.0
    t, valid, n_masked = P.temperature_planes(a, b, cal, model)
    assert list(n_masked) == [0, 0] and valid[0].all() and not valid[1].any() and np.isnan(t[1]).all()
    assert not P.bright_pixels(a + b)[1].any() and P.bright_pixels(a + b)[0].all()


def test_colour_behind_scene():
    """Two flames in the same columns, far first, each its own sheath temperature; channels by band integrals."""
    from lf_flame.simulate.scenes_temperature import BEHIND_PEAK_K, colour_behind_scene
    sensor = library_sensor(gains=GAINS)
    cs = colour_behind_scene(CAM, sensor, np.random.default_rng(3), 10.0)
    far, near = cs.scene.objects
    assert far["depth_offset_mm"] - near["depth_offset_mm"] == pytest.approx(10.0)
    assert abs(far["centre_x_mm"] - near["centre_x_mm"]) <= 0.3
    for k, pk in enumerate(BEHIND_PEAK_K):
        hot = cs.temperature_k[k][cs.soot[k] > 0]
        assert pk - 30 < hot.max() <= pk + 1e-9
        assert cs.scene.objects[k]["peak_k"] == pk
        i = np.unravel_index(np.argmax(cs.soot[k]), cs.soot[k].shape)
        s = band_integrals(sensor, cs.temperature_k[k][i], gains=True)
        r = cs.channel_radiance[k][:, i[0], i[1]]
        assert r[0] / r[1] == pytest.approx(s[0] / s[1], rel=1e-5)
    assert max(float(c.max()) for c in cs.channel_radiance) == pytest.approx(0.8, rel=1e-6)
    with pytest.raises(ValueError, match="two peak temperatures"):
        colour_behind_scene(CAM, sensor, np.random.default_rng(3), 10.0, peaks_k=(2000.0,))


def test_colour_flicker_frame_puts_the_hot_sheath_on_the_swayed_flame_and_flickers_its_temperature():
    """A recording's frame in colour: in every row the hottest texel lies on the (strongly swayed) flame's soot,
    the sheath temperature swings at the flame's frequency against its height, and the recording's one
    exposure makes the hotter frames brighter."""
    import dataclasses

    from lf_flame.simulate.scenes_temperature import FLAME_PEAK_K, colour_flicker_frame
    from lf_flame.simulate.scenes_time import flicker_sequence
    sensor = library_sensor(gains=GAINS)
    seq = flicker_sequence(CAM, np.random.default_rng(4), fps=100.0, duration_s=0.2)
    fine = dataclasses.replace(seq, flames=tuple(dataclasses.replace(f, sway=0.3) for f in seq.flames),
                               texels_per_lenslet=12.0)   # the sheath resolved: several texels across a flame
    for cs in (colour_flicker_frame(fine, CAM, sensor, i) for i in (0, 7)):
        for k in range(len(seq.flames)):
            rows = np.flatnonzero(cs.soot[k].max(axis=1) > 0.1 * cs.soot[k].max())   # the flame, not its faint tip
            hottest = np.argmax(cs.temperature_k[k][rows], axis=1)
            assert np.all(cs.soot[k][rows, hottest] > 0)
    frames = [colour_flicker_frame(seq, CAM, sensor, i, flicker_k=50.0, exposure=1.0) for i in range(seq.n_frames)]
    sheath = np.array([[o["peak_k"] for o in cs.scene.objects] for cs in frames])       # (frames, flames)
    heights = np.array([seq.heights_mm(i) for i in range(seq.n_frames)])
    for k, pk in enumerate(FLAME_PEAK_K):
        assert np.ptp(sheath[:, k]) > 50.0 and np.all(np.abs(sheath[:, k] - pk) <= 50.0 + 1e-9)
        assert np.corrcoef(sheath[:, k], heights[:, k])[0, 1] < -0.9
        hot, cold = np.argmax(sheath[:, k]), np.argmin(sheath[:, k])
        assert frames[hot].channel_radiance[k][0].max() > 1.2 * frames[cold].channel_radiance[k][0].max()
    own = colour_flicker_frame(seq, CAM, sensor, 3, flicker_k=50.0)
    assert max(float(c.max()) for c in own.channel_radiance) == pytest.approx(0.8, rel=1e-6)
    with pytest.raises(ValueError, match="one peak temperature per flame"):
        colour_flicker_frame(seq, CAM, sensor, 0, peaks_k=(2000.0,))
    with pytest.raises(ValueError, match="above base_k"):
        colour_flicker_frame(seq, CAM, sensor, 0, flicker_k=400.0)
    with pytest.raises(ValueError, match="frame must lie"):
        colour_flicker_frame(seq, CAM, sensor, seq.n_frames)


def test_matched_route_keeps_a_uniform_ratio_off_focus():
    """One flame-like blob with fine texture at +10 mm, one temperature (a uniform R/G ratio),
    through the CFA: each channel reconstructed from its own samples alone has its own
    aliasing, about 7 % in the ratio (p90 over the bright lenslets); the matched route (each
    channel through both channels' samples) keeps the ratio within a third of that,
    unfiltered."""
    from lf_flame.temperature.channels import MATCHED_KNOBS, channel_emission, route_operator
    from lf_flame.temperature.mosaic import channel_views
    sensor = library_sensor(gains=GAINS)
    y, x = np.mgrid[0:42, 0:42]
    soot = np.exp(-(((x - 21) / 7.0) ** 2 + ((y - 21) / 12.0) ** 2)) * (1 + 0.5 * np.cos(1.3 * x) * np.cos(0.9 * y))
    ch = soot[None] * np.moveaxis(band_integrals(sensor, np.full((42, 42), 1900.0), gains=True), -1, 0)
    ch = (ch * 0.8 / ch.max()).astype(np.float32)
    scene = Scene("blob", (Layer(ch[1], None, 10.0, (0.0, 0.0), CAM.field_of_view_mm(10.0)),), Effects(occlusion=False))
    raw = render_colour(CAM, scene, [ch], sensor, 64, 1)
    views = raw_to_views(raw, CAM.pixels_per_lenslet)
    chan = channel_views(raw.shape, sensor, CAM.pixels_per_lenslet)
    spread = {}
    for route in ("admm-cfa", "admm-cfa-matched"):
        info = {}
        a, b = channel_emission(route, views, chan, (0, 1), op=route_operator(CAM, [10.0], route), sigma=0.0,
                                ratio_filter={}, info=info)
        assert a.shape == b.shape == (1, CAM.n_rows, CAM.n_cols)          # binned to the lenslets
        bright = a + b > 0.3 * (a + b).max()
        spread[route] = np.percentile(np.abs(a[bright] / b[bright] / (ch[0].sum() / ch[1].sum()) - 1), 90)
    assert info["regime"] != "quiet" and info["knobs"] == MATCHED_KNOBS[info["regime"]]  # (fine texture: noise)
    assert (info["subsamples"], info["sigma"]) == (2, 0.0)
    assert spread["admm-cfa"] > 0.04
    assert spread["admm-cfa-matched"] < spread["admm-cfa"] / 3
    for bad, text in (((0, 0), "two different channel indices"), ((0, 5), "two different channel indices"),
                      ((0, 1), "holds no sample of R")):
        with pytest.raises(ValueError, match=text):          # a ratio of a channel with itself, or of no samples
            channel_emission("refocus-cfa", views, np.where(chan == 0, 1, chan) if bad == (0, 1) else chan, bad,
                             slopes=[CAM.slope_for_depth(10.0)])


def _smooth_blob():
    """A smooth flame-like blob at 1,900 K in focus through the CFA, noise-free and with about 14 dB
    of noise: (sensor, raw, noisy)."""
    sensor = library_sensor(gains=GAINS)
    y, x = np.mgrid[0:42, 0:42]
    soot = np.exp(-(((x - 21) / 7.0) ** 2 + ((y - 21) / 12.0) ** 2))
    ch = soot[None] * np.moveaxis(band_integrals(sensor, np.full((42, 42), 1900.0), gains=True), -1, 0)
    ch = (ch * 0.8 / ch.max()).astype(np.float32)
    scene = Scene("blob", (Layer(ch[1], None, 0.0, (0.0, 0.0), CAM.field_of_view_mm(0.0)),), Effects(occlusion=False))
    raw = render_colour(CAM, scene, [ch], sensor, 64, 1)
    noisy = raw + np.random.default_rng(0).normal(0, 0.2, raw.shape).astype(np.float32) * raw
    return sensor, raw, noisy


def test_cfa_noise_reads_each_channel_alone():
    """The noise of a colour light field measured on each channel's own samples: a smooth
    noise-free flame reads quiet (the CFA's pattern is not noise), the same at about 14 dB noisy;
    the sub-views hold one channel only."""
    from lf_flame.temperature.channels import cfa_noise
    from lf_flame.temperature.mosaic import channel_subviews, channel_views
    from lf_flame.tomo.defaults import ADMM_QUIET_NOISE
    sensor, raw, noisy = _smooth_blob()
    n = CAM.pixels_per_lenslet
    chan = channel_views(raw.shape, sensor, n)
    for c in (0, 1):
        assert (channel_subviews(chan.astype(float), chan, c) == c).all()
    assert cfa_noise(raw_to_views(raw, n), chan, (0, 1)) < ADMM_QUIET_NOISE
    assert cfa_noise(raw_to_views(noisy, n), chan, (0, 1)) > ADMM_QUIET_NOISE


def test_matched_route_takes_its_knobs_by_the_noise(monkeypatch):
    """``admm-cfa-matched`` solves a light field whose noise is below ``MATCHED_QUIET_NOISE`` with
    the quiet knobs, one above it with the noisy knobs, each with the guided ratio filter of its
    noise (the very noisy knobs and the wider filter from ``MATCHED_WIDE_NOISE``); given knobs and
    filter, it measures nothing."""
    from lf_flame.temperature import channels, mosaic
    quiet = dict(fills=2, lam=0.003, tv=0.0, l1=0.0)            # (few fills: the test's time)
    monkeypatch.setitem(channels.MATCHED_KNOBS, "quiet", quiet)
    monkeypatch.setitem(channels.MATCHED_KNOBS, "noisy", dict(channels.MATCHED_KNOBS["noisy"], fills=3))
    monkeypatch.setitem(channels.MATCHED_KNOBS, "very noisy", dict(channels.MATCHED_KNOBS["very noisy"], fills=4))
    sensor, raw, noisy = _smooth_blob()
    n, op = CAM.pixels_per_lenslet, channels.route_operator(CAM, [0.0], "admm-cfa-matched")
    chan = mosaic.channel_views(raw.shape, sensor, n)
    filtered = {}
    for image, thresholds, regime in ((raw, (0.01, 0.1), "quiet"), (raw, (0.003, 0.1), "noisy"),
                                      (noisy, (0.01, 0.1), "noisy"), (noisy, (0.01, 0.02), "very noisy")):
        monkeypatch.setattr(channels, "MATCHED_QUIET_NOISE", thresholds[0])   # the blob reads 0.004, noisy 0.03
        monkeypatch.setattr(channels, "MATCHED_WIDE_NOISE", thresholds[1])
        info = {}
        a, _ = channels.channel_emission("admm-cfa-matched", raw_to_views(image, n), chan, (0, 1), op=op, info=info)
        assert info["regime"] == regime
        assert info["knobs"] == channels.MATCHED_KNOBS[regime]
        assert info["ratio_filter"] == channels.MATCHED_RATIO_FILTER.get(regime, {}) and info["sigma"] == 0.0
        filtered[regime, image is noisy] = a
    assert not np.allclose(filtered["noisy", True], filtered["very noisy", True])   # the filter was applied
    info = {}
    channels.channel_emission("admm-cfa-matched", raw_to_views(noisy, n), chan, (0, 1), op=op, sigma=0.2,
                              knobs=quiet, ratio_filter={}, info=info)
    assert info == dict(knobs=quiet, sigma=0.2, ratio_filter={}, subsamples=2)


def test_guided_ratio_averages_the_noise_and_keeps_what_follows_the_guide():
    """The guided filter of the log ratio: a ratio linear in the log emission comes out nearly
    unchanged (eps well below the guide's local variance), noise on it is averaged, a constant
    ratio stays exact, and the pixels below the emission threshold keep their ratio; a Gaussian on both channels
    instead bends the ratio where it follows the brightness. The pixels bright enough for a
    temperature are those of the smoothed sum: noise does not raise the threshold and drop
    the flame's dim edge."""
    from lf_flame.temperature.ratio import guided_filter, guided_ratio, smooth_planes
    y, x = np.mgrid[0:40, 0:40]
    b = np.exp(-(((x - 20) / 8.0) ** 2 + ((y - 20) / 11.0) ** 2))[None] + 1e-6
    lr = 0.05 + 0.3 * np.log(b)                          # hotter where brighter: ln(a/b) linear in ln(b)
    a = b * np.exp(lr)
    fa, fb = guided_ratio(a, b, 2, 1e-4, guide_sigma=0.0)     # eps well below the guide's local variance
    bright = P.bright_pixels(a + b)
    np.testing.assert_allclose(fa + fb, a + b, rtol=1e-12)            # no smoothing of the sum asked for
    np.testing.assert_allclose(np.log(fa / fb)[~bright], lr[~bright], atol=1e-9)
    assert np.abs(np.log(fa / fb) - lr)[bright].max() < 2e-3          # the linear trend kept
    ga, gb = smooth_planes(a, 0.7), smooth_planes(b, 0.7)
    assert np.abs(np.log(ga / gb) - lr)[bright].max() > 5 * np.abs(np.log(fa / fb) - lr)[bright].max()
    ca, cb = guided_ratio(1.3 * b, b, 1, 0.03)
    np.testing.assert_allclose(ca / cb, 1.3, rtol=1e-9)
    np.testing.assert_allclose(ca + cb, smooth_planes(2.3 * b, 0.5), rtol=1e-9)
    rng = np.random.default_rng(3)
    na = a * np.exp(rng.normal(0, 0.05, a.shape))
    fa, fb = guided_ratio(na, b, 2, 1e-3, guide_sigma=0.0)
    before = np.std((np.log(na / b) - lr)[bright])
    after = np.std((np.log(fa / fb) - lr)[bright])
    assert after < 0.5 * before
    na, nb = a * rng.normal(1, 0.3, a.shape), b * rng.normal(1, 0.3, a.shape)   # noisy channels
    raw = P.bright_pixels(na + nb).sum()
    fa, fb = guided_ratio(na, nb, 2, 1e-3)
    kept = P.bright_pixels(fa + fb).sum()
    assert kept > raw and abs(kept - bright.sum()) < 0.1 * bright.sum()
    with pytest.raises(ValueError, match="radius"):
        guided_filter(lr[0], lr[0], bright[0], 0, 0.1)
    with pytest.raises(ValueError, match="one 2-D shape"):
        guided_filter(lr[0], lr[0][1:], bright[0], 1, 0.1)


def test_contour_ratio_averages_along_the_sheath_and_keeps_its_profile_across():
    """Averaging the channels along the brightness contours: on a ring-shaped sheath whose ratio
    peaks across it, the profile across comes out nearly unchanged where an isotropic Gaussian of
    the same length flattens it; noise along the ring is averaged; a constant ratio stays exact
    and the sum is the smoothed sum; a length that is not positive is refused."""
    from lf_flame.temperature.ratio import contour_ratio, filter_ratio, guided_ratio, smooth_planes
    y, x = np.mgrid[0:64, 0:64]
    r = np.hypot(x - 31.5, y - 31.5)
    b = np.exp(-((r - 18) / 4.0) ** 2)[None] + 1e-6
    lr = 0.3 * np.exp(-((r - 18) / 2.5) ** 2)[None]           # hottest on the sheath, as a flame's
    a = b * np.exp(lr)
    bright = P.bright_pixels(a + b)
    fa, fb = contour_ratio(a, b, 2.0, guide_sigma=0.0)
    kept = np.abs(np.log(fa / fb) - lr)[bright].max()
    ga, gb = smooth_planes(a, 2.0), smooth_planes(b, 2.0)
    assert kept < 0.03 and np.abs(np.log(ga / gb) - lr)[bright].max() > 4 * kept
    na = a * np.random.default_rng(3).normal(1, 0.1, a.shape)
    fa, fb = contour_ratio(na, b, 2.0, guide_sigma=0.0)
    assert np.std((np.log(fa / fb) - lr)[bright]) < 0.5 * np.std((np.log(na / b) - lr)[bright])
    ca, cb = contour_ratio(1.3 * b, b, 3.0)
    np.testing.assert_allclose(ca / cb, 1.3, rtol=1e-9)
    np.testing.assert_allclose(ca + cb, smooth_planes(2.3 * b, 0.5), rtol=1e-9)
    np.testing.assert_allclose(filter_ratio(a, b, 1, 0.1, contour=2.0), guided_ratio(*contour_ratio(a, b, 2.0), 1, 0.1))
    with pytest.raises(ValueError, match="positive length"):
        contour_ratio(a, b, 0.0)
    with pytest.raises(ValueError, match="emission stacks"):
        contour_ratio(a, b[:, 1:], 2.0)


def test_ratio_filters_give_no_ratio_where_neither_channel_holds_emission():
    """Pixels where both channels' emission is 0 (admm's non-negative planes hold such holes) have no ratio: the
    filters' smoothed sum spreads light into them, and each filter returns both channels 0 there, not a share of
    0.5 (ratio 1: one temperature of the calibration's, 2,600 K on a user's colour camera, at every such pixel a
    low --min-fraction reached). Their neighbours keep their filtered ratio."""
    from lf_flame.temperature.ratio import contour_ratio, filter_ratio, guided_ratio
    y, x = np.mgrid[0:40, 0:40]
    b = np.exp(-(((x - 20) / 8.0) ** 2 + ((y - 20) / 11.0) ** 2))[None]
    a = 1.3 * b
    hole = (np.abs(y - 20) <= 1) & (np.abs(x - 14) <= 1)
    a, b = np.where(hole, 0.0, a), np.where(hole, 0.0, b)
    for fa, fb in (guided_ratio(a, b, 1, 0.1, min_fraction=0.01), contour_ratio(a, b, 2.0, min_fraction=0.01),
                   filter_ratio(a, b, 1, 0.1, contour=2.0)):
        assert (fa[0][hole] == 0).all() and (fb[0][hole] == 0).all()
        near = ~hole & (a[0] + b[0] > 0.05)
        np.testing.assert_allclose(fa[0][near] / fb[0][near], 1.3, rtol=1e-9)


def test_a_channel_without_light_is_named():
    """A colour capture whose red (or green) pixels hold nothing is refused naming that channel, before any solve."""
    from lf_flame.temperature.channels import channel_emission
    chan = np.indices((3, 3, 4, 4)).sum(axis=0) % 2            # two channels, R (0) and G (1), interleaved
    for dark, name in ((0, "R"), (1, "G")):
        views = np.where(chan == dark, 0.0, 0.5)
        with pytest.raises(ValueError, match=f"the {name} channel has no sample with signal"):
            channel_emission("admm-cfa", views, chan, (0, 1), op=object())


def test_cfa_blind_marks_the_slopes_where_half_the_lenslets_have_no_red_sample():
    """At an odd-integer slope (odd pixels per lenslet) the points on every other lenslet row
    have no red sample in any view; elsewhere every row has one. ``cfa_blind`` flags exactly
    the former among these slopes, and no plane with an even number of pixels per lenslet."""
    from lf_flame.temperature.mosaic import cfa_blind, channel_views
    n = CAM.pixels_per_lenslet
    chan = channel_views((CAM.n_rows * n, CAM.n_cols * n), library_sensor(), n)
    red_row = (chan == 0).any(axis=(1, 3))                    # (view row u, lenslet row k)
    slopes = [-3.0, -1.0, -0.95, 0.0, 0.5, 1.0, 1.3, 2.0, 3.0]
    seen = []
    for s in slopes:
        rows = np.arange(4, CAM.n_rows - 4)
        k = rows[:, None] + np.rint(s * (np.arange(n) - (n - 1) / 2)).astype(int)[None]
        ok = (k >= 0) & (k < CAM.n_rows)
        seen.append(np.mean([np.any(red_row[np.arange(n)[ok[i]], k[i][ok[i]]]) for i in range(len(rows))]))
    seen = np.array(seen)
    assert np.all((seen < 0.6) | (seen > 0.95))                # half the rows, or all of them
    np.testing.assert_array_equal(cfa_blind(slopes, n), seen < 0.75)
    assert not cfa_blind(slopes, 14).any()
