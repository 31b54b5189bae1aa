"""``lf-flame calibrate-temperature`` and ``lf-flame temperature`` on a small colour camera."""
import json

import h5py
import numpy as np
import pandas as pd
import pytest

from lf_flame.cli import main
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.optics.colour import band_integrals, library_sensor
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate.colour import render_colour
from lf_flame.simulate.layers import Effects, Layer, Scene
from lf_flame.simulate.scenes_temperature import furnace_scene
from lf_flame.temperature.channels import DECODED_KNOBS
from lf_flame.temperature.mosaic import channel_sum_views, channel_views

CAM = PlenopticCamera(n_rows=21, n_cols=21)
GAINS = (1.0, 1.3, 0.7)
COOL, HOT = 1750.0, 1900.0


def _save(path, raw, sensor):
    np.savez(path, raw=raw, camera=json.dumps(CAM.to_dict()),
             sensor=json.dumps(dict(name=sensor.name, pattern=sensor.pattern, phase=list(sensor.phase))))
    return str(path)


def _planted(sensor, seed=2):
    """A cooler rectangle (left) and a hotter one (right) of soot on the focal plane."""
    soot = np.zeros((42, 42))
    temp = np.full((42, 42), COOL)
    soot[10:32, 8:18] = 1.0
    soot[10:32, 24:34] = 1.0
    temp[:, 21:] = HOT
    ch = soot[None] * np.moveaxis(band_integrals(sensor, temp, gains=True), -1, 0)
    ch = (ch * 0.8 / ch.max()).astype(np.float32)
    h, w = CAM.field_of_view_mm(0.0)
    scene = Scene("planted", (Layer(ch[1], None, 0.0, (0.0, 0.0), (h, w)),), Effects(occlusion=False))
    return render_colour(CAM, scene, [ch], sensor, 16, seed)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("temperature")
    sensor = library_sensor(gains=GAINS)
    bb = []
    for t in (1600.0, 2000.0, 2400.0):
        sc, ch = furnace_scene(CAM, sensor, t)
        bb.append(_save(d / f"bb{t:.0f}.npz", render_colour(CAM, sc, ch, sensor, 2, 0), sensor))
    flame = _save(d / "flame.npz", _planted(sensor), sensor)
    cal = str(d / "bb.json")
    args = ["calibrate-temperature", *bb]
    for t in (1600, 2000, 2400):
        args += ["--temperature", str(t)]
    assert main(args + ["--out", cal]) == 0
    return dict(dir=d, bb=bb, flame=flame, cal=cal, sensor=sensor)


def test_calibrate_temperature_finds_the_gain_ratio(files, capsys):
    d = json.loads(open(files["cal"]).read())
    assert d["gain_ratio"] == pytest.approx(GAINS[0] / GAINS[1], rel=1e-3)
    assert d["channels"] == ["R", "G"] and d["sensor_name"] == files["sensor"].name
    assert max(abs(r) for r in d["fit_residuals_k"]) < 1.0
    # one temperature per image
    assert main(["calibrate-temperature", *files["bb"], "--temperature", "1600", "--out",
                 str(files["dir"] / "x.json")]) == 2
    capsys.readouterr()       # a missing image is named (a missing second decoded one had read as another sensor's)
    assert main(["calibrate-temperature", files["bb"][0], str(files["dir"] / "nonexist.h5"), "--temperature", "1600",
                 "--temperature", "2000", "--out", str(files["dir"] / "x.json")]) == 2
    assert "blackbody image file not found" in capsys.readouterr().err
    capsys.readouterr()        # one blackbody: fitted, and the check it cannot make said
    assert main(["calibrate-temperature", files["bb"][0], "--temperature", "1600", "--out",
                 str(files["dir"] / "one.json")]) == 0
    assert "warning: the calibration's blackbodies are at one temperature (1600 K)" in capsys.readouterr().err


def test_temperatures_beyond_the_blackbodies_are_said_to_be_extrapolated(files, capsys):
    """The flames (1750 and 1900 K) read with a calibration of blackbodies at 2000 and 2400 K: the share of each
    plane's temperatures beyond that range is printed as extrapolated (they had been printed as any others); with
    the 1600-2400 K calibration, none."""
    hot = str(files["dir"] / "hot.json")
    assert main(["calibrate-temperature", *files["bb"][1:], "--temperature", "2000", "--temperature", "2400", "--out",
                 hot]) == 0
    for cal, said in ((hot, True), (files["cal"], False)):
        capsys.readouterr()
        assert main(["temperature", files["flame"], "--calibration", cal, "--depths", "0", "--no-figure", "--out",
                     str(files["dir"] / "ex.h5")]) == 0
        assert ("beyond the blackbodies' 2000-2400 K: extrapolated" in capsys.readouterr().out) == said


@pytest.mark.parametrize("phase", [(1, 1), (0, 1), (1, 0)])
def test_a_colour_filter_array_read_at_the_wrong_phase_is_refused(files, capsys, phase):
    """Read at another phase the RGGB mosaic's red samples are blue's or green's, its green samples red's and blue's:
    their ratio rises with the blackbodies' temperature where a blackbody's red/green falls, whatever the gains;
    calibrate-temperature refuses it, naming the colour filter array and the phase the raw images fit at, rather
    than fitting a gain ratio."""
    args = ["calibrate-temperature", *files["bb"]]
    for t in (1600, 2000, 2400):
        args += ["--temperature", str(t)]
    capsys.readouterr()
    assert main(args + ["--cfa-phase", *map(str, phase), "--out", str(files["dir"] / "wrong.json")]) == 2
    err = capsys.readouterr().err
    assert "rises with the blackbody's temperature" in err and f"phase {phase}" in err
    assert "These images fit at phase (0, 0) (residuals within 0.0 K)" in err     # the one they were made with
    assert not (files["dir"] / "wrong.json").exists()


def test_a_clipped_or_mislabelled_blackbody_is_named(files, tmp_path, capsys):
    """Blackbody images with clipped pixels are refused (a clipped channel's mean reads low: the gain ratio with it);
    a temperature given wrong that still rises with the images leaves residuals of tens of K: a warning (the images'
    own temperatures leave none); a raw image without a stored camera that is not the paper camera's lenslet images
    is refused naming the decoding it needs."""
    with np.load(files["bb"][2]) as z:
        raw, meta = z["raw"], {k: z[k] for k in ("camera", "sensor")}
    np.savez(tmp_path / "clipped.npz", raw=np.minimum(raw * 1.5, 1.0).astype(np.float32), **meta)
    temps = [x for t in (1600, 2000, 2400) for x in ("--temperature", str(t))]
    capsys.readouterr()
    assert main(["calibrate-temperature", *files["bb"][:2], str(tmp_path / "clipped.npz"), *temps,
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "of its lit samples are clipped" in capsys.readouterr().err and not (tmp_path / "c.json").exists()
    assert main(["calibrate-temperature", *files["bb"], *temps, "--out", str(tmp_path / "ok.json")]) == 0
    assert "warning" not in capsys.readouterr().err
    wrong = [x for t in (1600, 1800, 2400) for x in ("--temperature", str(t))]
    assert main(["calibrate-temperature", *files["bb"], *wrong, "--out", str(tmp_path / "w.json")]) == 0
    err = capsys.readouterr().err
    assert "warning: the calibration's fit leaves a residual of" in err and "1600, 1800, 2400 K" in err, err
    # and each time the calibration is read: its temperatures are as far off as its fit
    assert main(["temperature", files["flame"], "--calibration", str(tmp_path / "w.json"), "--depths", "0",
                 "--no-figure", "--out", str(tmp_path / "w.h5")]) == 0
    assert "w.json: the calibration's fit leaves a residual of" in capsys.readouterr().err
    np.save(tmp_path / "cropped.npy", raw[:310, :310])
    assert main(["calibrate-temperature", str(tmp_path / "cropped.npy"), str(tmp_path / "cropped.npy"),
                 "--temperature", "1600", "--temperature", "2400", "--out", str(tmp_path / "n.json")]) == 2
    assert "stores no camera: it was taken as the paper camera's raw image" in capsys.readouterr().err


def test_blackbody_temperatures_given_in_another_order_are_named(files, capsys):
    """The blackbodies' temperatures given in reverse order: the ratio rises with the temperatures given, and the
    refusal names the temperatures as given beside the colour filter array."""
    args = ["calibrate-temperature", *files["bb"]]
    for t in (2400, 2000, 1600):
        args += ["--temperature", str(t)]
    capsys.readouterr()
    assert main(args + ["--out", str(files["dir"] / "reversed.json")]) == 2
    err = capsys.readouterr().err
    assert "the temperatures given are not the images'" in err and "2400 K, 2000 K, 1600 K" in err, err


def test_temperature_on_planes_where_no_flame_stands_is_warned_of(files, capsys):
    """Planes given where no flame stands (the flame is at 0 mm): the misfit of reconstruct's levelled light field
    on them is warned of and recorded, as reconstruct warns; it had printed their temperatures without a word. On
    the flame's own plane, no warning."""
    out = str(files["dir"] / "off.h5")
    capsys.readouterr()
    for depth, warned in (("6", True), ("0", False)):
        assert main(["temperature", files["flame"], "--calibration", files["cal"], "--depths", depth, "--no-figure",
                     "--out", out]) == 0
        err = capsys.readouterr().err
        assert ("of the light field unexplained" in err) == warned, err
        assert "clipped" not in err
        with h5py.File(out, "r") as f:
            assert (json.loads(f.attrs["misfit"])["misfit"] > 0.1) == warned
    # over-exposed: its clipped pixels are noted, even under reconstruct's warning level (a ratio's channels clip apart)
    with np.load(files["flame"]) as z:
        raw = z["raw"]
    bright = _save(files["dir"] / "bright.npz", np.minimum(raw * 1.27, 1.0),           # 5 % of its lit pixels
                   library_sensor(gains=GAINS))
    assert main(["temperature", bright, "--calibration", files["cal"], "--depths", "0", "--no-figure", "--out",
                 out]) == 0
    assert "note: 5.2 % of the lit pixels are clipped" in capsys.readouterr().err
    with h5py.File(out, "r") as f:
        assert 0 < json.loads(f.attrs["clipped_share"])


def test_temperature_round_trip(files, capsys):
    out = files["dir"] / "T.h5"
    assert main(["temperature", files["flame"], "--calibration", files["cal"], "--depths", "0", "--out",
                 str(out)]) == 0
    assert out.with_suffix(".png").stat().st_size > 0
    with h5py.File(out, "r") as f:
        t, valid, dim = f["temperature_k"][:], f["valid"][:], f["dim"][:]
        assert f["temperature_k"].attrs["units"] == "K"
        assert list(f["depths_mm"][:]) == [0.0]
        assert json.loads(f.attrs["provenance"])["versions"]
        # the default route and its grid are recorded
        assert f.attrs["route"] == "admm-cfa-matched"
        assert json.loads(f.attrs["route_settings"])["subsamples"] == 2
        n_masked, n_dim = f["n_masked"][:], f["n_dim"][:]
        assert list(f["cfa_blind"][:]) == [False]           # slope 0: both CFA phases in every lenslet
    assert t.shape == (1, 21, 21)
    # masked pixels carry no temperature; dim ones are masked; the counts are the masks'
    assert np.array_equal(np.isfinite(t), valid)
    assert not (valid & dim).any() and dim.any()
    assert n_dim[0] == dim.sum() and n_masked[0] == (~valid & ~dim).sum()
    # each rectangle's temperature (lenslets inside it), in K
    assert np.nanmedian(t[0][5:16, 5:8]) == pytest.approx(COOL, abs=25.0)
    assert np.nanmedian(t[0][5:16, 13:16]) == pytest.approx(HOT, abs=25.0)
    assert np.isnan(t[0][0:3, :]).all()                   # the dark background


def test_a_temperature_whose_every_ratio_is_outside_the_table_is_warned_of(files, tmp_path, capsys):
    """A calibration whose gain ratio is far from the channels' (another camera's, or the channels misread) leaves
    every bright pixel without a temperature: warned of, naming the likely causes; the route's settings print as a
    line, not a Python dict."""
    capsys.readouterr()
    assert main(["temperature", files["flame"], "--calibration", files["cal"], "--depths", "0", "--no-figure",
                 "--out", str(tmp_path / "T.h5")]) == 0
    out, err = capsys.readouterr()
    assert "no temperature of the table gives" not in err
    assert "(admm-cfa-matched: " in out and "{" not in out, out
    d = json.loads(open(files["cal"]).read())
    d["gain_ratio"] *= 50.0
    (tmp_path / "other.json").write_text(json.dumps(d))
    assert main(["temperature", files["flame"], "--calibration", str(tmp_path / "other.json"), "--depths", "0",
                 "--no-figure", "--out", str(tmp_path / "T2.h5")]) == 0
    assert "bright pixels have a R/G ratio no temperature of the table gives" in capsys.readouterr().err


def test_temperature_auto_depth_and_refocus_route(files):
    out = files["dir"] / "Tauto.h5"
    assert main(["temperature", files["flame"], "--calibration", files["cal"], "--route", "refocus-cfa",
                 "--no-figure", "--out", str(out)]) == 0
    assert not out.with_suffix(".png").exists()                   # --no-figure: the HDF5 only
    with h5py.File(out, "r") as f:
        depths, t = f["depths_mm"][:], f["temperature_k"][:]
        found = json.loads(f.attrs["found_depths"])
    assert len(depths) == 1 and abs(depths[0]) < 0.5 and len(found) == 1
    assert np.nanmedian(t[0][5:16, 13:16]) == pytest.approx(HOT, abs=25.0)


@pytest.mark.parametrize("given", [[], ["--depth", "-0.8", "--depth", "0.8"]], ids=["found", "given"])
def test_found_planes_near_each_other_keep_their_own_flames_temperature(files, given):
    """Two flames side by side 1.6 mm apart in depth (2.7 lenslets of parallax across the aperture: the data
    barely tell the planes apart): with the depths found, each plane holds its own flame and its temperature,
    as 'reconstruct' holds such planes (its found_support), not half of each flame at their mean temperature; with
    the planes given (--depth), the same: the depth search's regions put on the nearest given plane."""
    sensor = files["sensor"]
    h, w = CAM.field_of_view_mm(0.0)
    layers, channels = [], []
    for depth, cols, temp in ((-0.8, slice(2, 10), COOL), (0.8, slice(32, 40), HOT)):
        soot = np.zeros((42, 42))
        soot[10:32, cols] = 1.0
        ch = soot[None] * np.moveaxis(band_integrals(sensor, np.full((42, 42), temp), gains=True), -1, 0)
        channels.append((ch * 0.8 / ch.max()).astype(np.float32))
        layers.append(Layer(channels[-1][1], None, depth, (0.0, 0.0), (h, w)))
    raw = render_colour(CAM, Scene("near", tuple(layers), Effects(occlusion=False)), channels, sensor, 16, 3)
    out = files["dir"] / f"Tnear{len(given)}.h5"
    assert main(["temperature", _save(files["dir"] / "near.npz", raw, sensor), "--calibration", files["cal"],
                 *given, "--no-figure", "--out", str(out)]) == 0
    with h5py.File(out, "r") as f:
        depths, t, e = f["depths_mm"][:], f["temperature_k"][:], f["emission"][:].sum(axis=0)
        assert json.loads(f.attrs["route_settings"])["support"] == "near planes"
    assert depths == pytest.approx([-0.8, 0.8], abs=0.3)
    left, right = e[:, :, :10].sum(axis=(1, 2)), e[:, :, 11:].sum(axis=(1, 2))
    assert right[0] < 0.05 * left[0] and left[1] < 0.05 * right[1]
    assert np.nanmedian(t[0][:, :10]) == pytest.approx(COOL, abs=30.0)
    assert np.nanmedian(t[1][:, 11:]) == pytest.approx(HOT, abs=30.0)


def test_a_raw_colour_mosaic_is_levelled_for_the_emission_and_its_planes_are_temperatures(files, capsys):
    """A perfect grid's raw colour mosaic (the sensor stored beside it): reconstruct levels its red and green samples
    into one light field, as it levels a decoded colour capture, instead of fitting the mosaic's checkerboard of
    channel levels; temperature takes reconstruct's planes."""
    out = files["dir"] / "mono.h5"
    assert main(["reconstruct", files["flame"], "--no-figure", "--out", str(out)]) == 0
    assert "colour capture: channels [0, 1] levelled" in capsys.readouterr().out
    with h5py.File(out, "r") as f:
        depths, residuals = f["depths_mm"][:], f["residuals"][:]
        assert "levelled" in f.attrs["monochrome"]
    assert depths == pytest.approx([0.0], abs=0.3) and residuals[-1] < 0.1     # the mosaic as it is: 0.4
    t_out = files["dir"] / "Tplanes.h5"
    capsys.readouterr()
    assert main(["temperature", files["flame"], "--calibration", files["cal"], "--route", "admm-cfa", "--no-figure",
                 "--out", str(t_out)]) == 0
    assert "its worst plane's p90 error is 283 K noise-free" in capsys.readouterr().err    # the quick route said so
    with h5py.File(t_out, "r") as f:
        assert list(f["depths_mm"][:]) == list(depths)
        assert "as reconstruct" in f.attrs["depths_from"]


def test_a_perfect_grids_colour_recording_is_levelled_as_reconstruct_levels_a_capture(files, capsys, monkeypatch):
    """A recording of a colour camera on a perfect grid (no calibration; its sensor in the file's attributes): each
    frame's mosaic is levelled exactly as reconstruct levels the same raw capture (the same views, the same samples
    left out: blue and clipped), and the planes found in its first frame are the flame's, as reconstruct's."""
    from lf_flame.real.lightfield import from_raw
    from lf_flame.recordings.job import SequenceJob
    from lf_flame.temperature.mosaic import monochrome_light_field
    raw, s = np.load(files["flame"])["raw"], files["sensor"]
    sensor = dict(name=s.name, pattern=s.pattern, phase=list(s.phase))
    lf = monochrome_light_field(from_raw(raw, CAM, sensor=s))
    job = SequenceJob(None, CAM, 100.0, (0.0,), (0.0,), (None,), "reconstruct-admm", sensor=sensor)
    views, leave = job.frame(raw)
    assert np.array_equal(views, lf.views) and np.array_equal(leave, lf.leave_out)
    assert job.fit_data(views, leave)[1] is leave           # the levelled views not compared with the level again
    rec, out = files["dir"] / "colour_recording.h5", files["dir"] / "colour_recording"
    with h5py.File(rec, "w") as f:
        f["frames"] = np.stack([raw, 0.9 * raw, raw]).astype(np.float32)
        f.attrs.update(fps=100.0, camera=json.dumps(CAM.to_dict()), sensor=json.dumps(sensor))
    import lf_flame.cli.planes as planes
    searched, found_planes = [], planes.found_planes
    monkeypatch.setattr(planes, "found_planes", lambda lf, **k: searched.append(lf) or found_planes(lf, **k))
    capsys.readouterr()
    assert main(["sequence", str(rec), "--route", "reconstruct-admm", "--quiet", "--out", str(out)]) == 0
    assert "levelled into one light field" in capsys.readouterr().out
    assert np.array_equal(searched[0].views, lf.views)      # the first frame's depths found on it levelled
    job = json.loads((out / "job.json").read_text())
    assert job["depths_mm"] == pytest.approx([0.0], abs=0.3)
    assert job["reconstruction"]["admm_noise"] < 0.02        # the mosaic as it is reads as noise: 0.08
    # each frame's saturated samples are its clipped red and green ones, not its blue ones (left out of every frame)
    import pandas as pd
    from lf_flame.real.clipping import found_level
    from lf_flame.refocus.shift_and_sum import raw_to_views
    chan = raw_to_views(s.channel_map(raw.shape).astype(np.float32), CAM.pixels_per_lenslet)
    n_sat = pd.read_csv(out / "frames.csv").groupby("frame").n_saturated.first()
    for i, frame in enumerate([raw, 0.9 * raw, raw]):
        v = raw_to_views(frame.astype(np.float32), CAM.pixels_per_lenslet)
        assert n_sat[i] == np.count_nonzero((v >= found_level(v)) & (chan < 2)), (i, n_sat[i])


def test_a_colour_recording_gets_each_frames_temperature_as_one_capture_would(files, capsys):
    """A recording of raw colour frames (an HDF5 stack, its sensor in the file's attributes): each frame's planes get
    the temperature 'temperature' gives that frame as one capture (the route's operator built once for all), the
    CSV each frame's and plane's median; a monochrome recording (rendered without a sensor) is refused."""
    import pandas as pd
    s = files["sensor"]
    raws = [_planted(s, seed) for seed in (2, 3, 4)]
    rec, out = files["dir"] / "colour_frames.h5", files["dir"] / "Trec.h5"
    with h5py.File(rec, "w") as f:
        f["frames"] = np.stack(raws).astype(np.float32)
        f.attrs.update(fps=50.0, camera=json.dumps(CAM.to_dict()),
                       sensor=json.dumps(dict(name=s.name, pattern=s.pattern, phase=list(s.phase))))
    args = ["--calibration", files["cal"], "--route", "admm-cfa", "--depth", "0", "--no-figure"]
    assert main(["temperature", str(rec), *args, "--out", str(out)]) == 0
    one = files["dir"] / "Tframe1.h5"
    assert main(["temperature", _save(files["dir"] / "frame1.npz", raws[1], s), *args, "--out", str(one)]) == 0
    with h5py.File(out) as f, h5py.File(one) as g:
        t, single = f["temperature_k"][...], g["temperature_k"][...]
        assert t.shape == (3,) + single.shape and list(f["times_s"][...]) == [0.0, 0.02, 0.04]
        np.testing.assert_allclose(t[1], single, rtol=1e-5, equal_nan=True)
        assert np.array_equal(f["valid"][1], g["valid"][...])
    df = pd.read_csv(out.with_suffix(".csv"))
    assert len(df) == 3 and df.median_k[1] == pytest.approx(float(np.median(single[np.isfinite(single)])), rel=1e-5)
    for frame in t:                                          # each frame: the cooler rectangle left, the hotter right
        half = frame.shape[-1] // 2
        assert np.nanmedian(frame[..., :half]) < np.nanmedian(frame[..., half:]) - 50
    mono = files["dir"] / "mono_frames.h5"
    with h5py.File(mono, "w") as f:
        f["frames"] = np.stack(raws).astype(np.float32)
        f.attrs.update(fps=50.0, camera=json.dumps(CAM.to_dict()), sequence="{}")
    capsys.readouterr()
    assert main(["temperature", str(mono), *args, "--out", str(files["dir"] / "never.h5")]) == 2
    assert "monochrome recording" in capsys.readouterr().err


def test_an_image_that_is_not_a_blackbody_is_refused_as_one(files, tmp_path, capsys):
    """A flame image, or a constant one, given to calibrate-temperature as a blackbody: refused (its channels' ratio
    not the same over the field; no mosaic), where each had been taken and fitted a gain ratio (0.71 and 0.46, the
    temperatures of flames then 700 K low)."""
    np.save(tmp_path / "const.npy", np.full(CAM.sensor_shape, 0.3, np.float32))
    for image, text in ((files["flame"], "not a blackbody filling the field evenly"),
                        (str(tmp_path / "const.npy"), "no colour filter mosaic")):
        assert main(["calibrate-temperature", image, "--temperature", "1600", "--out", str(tmp_path / "x.json")]) == 2
        assert text in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_wrong_calibration_refused(files, capsys):
    out = str(files["dir"] / "never.h5")
    sigma = library_sensor("Sigma SDMerill (NPL)")
    other = _save(files["dir"] / "sigma.npz", np.load(files["flame"])["raw"], sigma)
    assert main(["temperature", other, "--calibration", files["cal"], "--depths", "0", "--out", out]) == 2
    assert "made for sensor 'Nikon 5100 (NPL)'" in capsys.readouterr().err
    # the CFA's phase given on the command line, not the calibration's
    assert main(["temperature", files["flame"], "--calibration", files["cal"], "--cfa-phase", "1", "1", "--depths",
                 "0", "--out", out]) == 2
    assert "phase (1, 1)" in capsys.readouterr().err
    # a calibration of one channel against itself
    d = json.loads(open(files["cal"]).read())
    d["channels"] = ["G", "G"]
    bad = files["dir"] / "bad.json"
    bad.write_text(json.dumps(d))
    assert main(["temperature", files["flame"], "--calibration", str(bad), "--depths", "0", "--out", out]) == 2
    assert "two different" in capsys.readouterr().err
    # a gain ratio edited into a string, or zero: named (a string had ended in a TypeError traceback)
    for gain in ("1.0", 0.0):
        d = json.loads(open(files["cal"]).read())
        d["gain_ratio"] = gain
        bad.write_text(json.dumps(d))
        assert main(["temperature", files["flame"], "--calibration", str(bad), "--depths", "0", "--out", out]) == 2
        assert "malformed temperature calibration (gain_ratio must be a positive number" in capsys.readouterr().err
    assert not (files["dir"] / "never.h5").exists()


def test_channel_sum_has_no_cfa_checkerboard():
    """A uniform furnace: the mosaic's views alternate R/G/B from lenslet to lenslet; the channel sum is flat."""
    sensor = library_sensor(gains=GAINS)
    sc, ch = furnace_scene(CAM, sensor, 2000.0)
    raw = render_colour(CAM, sc, ch, sensor, 2, 0)
    views = raw_to_views(raw, CAM.pixels_per_lenslet)
    chan = channel_views(raw.shape, sensor, CAM.pixels_per_lenslet)
    v = views[7, 7, 5:16, 5:16]                             # the central view, central lenslets
    assert v.std() / v.mean() > 0.1
    s = channel_sum_views(views, chan)[7, 7, 5:16, 5:16]
    assert s.std() / s.mean() < 0.01


def test_a_colour_capture_with_one_site_of_a_channel_dead_is_refused_naming_it(files, tmp_path, capsys):
    """A colour mosaic whose green pixels at one site of the 2 x 2 tile read nothing (the other greens light) had its
    channels' ratio read as a temperature (about 1,080 K for flames at 1,800-2,050 K, exit 0): refused naming the
    channel and its sites, as a blackbody and in a recording's frame (that frame's rows failed, the others kept)."""
    from lf_flame.temperature.mosaic import refuse_dead_site
    d = files
    with np.load(d["flame"]) as z:
        raw = z["raw"].copy()
    refuse_dead_site(raw, d["sensor"], "flame")                      # a clean capture passes
    sites = np.argwhere(d["sensor"].channel_map((2, 2)) == 1)        # the green sites
    i, j = sites[0]
    dead = raw.copy()
    dead[i::2, j::2] = 0.0
    bad = _save(tmp_path / "dead.npz", dead, d["sensor"])
    assert main(["temperature", bad, "--calibration", d["cal"], "--depths", "0", "--out", str(tmp_path / "T.h5"),
                 "--no-figure"]) == 2
    err = capsys.readouterr().err
    assert "its G pixels disagree" in err and f"0 at tile row {i}, column {j}" in err
    assert not (tmp_path / "T.h5").exists()
    bb = np.load(d["bb"][0])["raw"].copy()
    bb[i::2, j::2] *= 0.3
    args = ["calibrate-temperature", _save(tmp_path / "bb.npz", bb, d["sensor"]), d["bb"][1], d["bb"][2]]
    assert main(args + ["--temperature", "1600", "--temperature", "2000", "--temperature", "2400",
                        "--out", str(tmp_path / "bb.json")]) == 2
    assert "one site of the G channel is dead or dimmed" in capsys.readouterr().err
    # a recording: the frame with the dead site fails, the others are as without it
    frames = np.stack([raw, dead, raw])
    with h5py.File(tmp_path / "rec.h5", "w") as f:
        f["frames"] = frames
        f.attrs["fps"] = 10.0
        f.attrs["camera"] = json.dumps(CAM.to_dict())
        f.attrs["sensor"] = json.dumps(d["sensor"].record())
    assert main(["temperature", str(tmp_path / "rec.h5"), "--calibration", d["cal"], "--depths", "0",
                 "--out", str(tmp_path / "Tr.h5"), "--no-figure"]) == 0
    rows = pd.read_csv(tmp_path / "Tr.csv")
    assert rows.failure.notna().tolist() == [False, True, False]
    assert "its G pixels disagree" in rows.failure[1] and np.isfinite(rows.median_k[[0, 2]]).all()


def test_temperature_refuses_a_monochrome_light_field(files, tmp_path, capsys):
    """A light field without colour channels: a monochrome render (its record), or an image with no
    mosaic (the same colour raw image with its 2 x 2 phases averaged: the record stripped), exit 2
    naming the cause; the colour image itself is not refused by the mosaic check."""
    from lf_flame.cli.temperature_planes import _refuse_monochrome
    d = files
    with np.load(d["flame"]) as z:
        raw = z["raw"]
    _refuse_monochrome(str(d["flame"]))                    # a colour capture passes
    np.save(tmp_path / "colour.npy", raw)
    _refuse_monochrome(str(tmp_path / "colour.npy"))        # no record: its mosaic tells
    R, C = raw.shape
    even = np.pad(raw, ((0, R % 2), (0, C % 2)), mode="edge")
    grey = even.reshape(even.shape[0] // 2, 2, even.shape[1] // 2, 2).mean(axis=(1, 3)).repeat(2, 0).repeat(2, 1)
    grey = grey[:R, :C]
    np.save(tmp_path / "grey.npy", grey)
    np.savez(tmp_path / "mono.npz", raw=grey, camera=json.dumps(CAM.to_dict()))
    # an RGB image whose average keeps the mosaic (as a demosaiced output's did, 16-bit): averaged to gray, its phases
    # had been read as the CFA's (600-750 K too hot on a user's camera); refused, and as a blackbody too
    from skimage import io
    rgb = raw[..., None] * np.array([1.0, 0.8, 0.6])
    io.imsave(tmp_path / "rgb.tif", (65535 * rgb / rgb.max()).astype(np.uint16), check_contrast=False)
    cam = tmp_path / "cam.toml"                                        # the image's camera, as a user gives it
    cam.write_text("[camera]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in CAM.to_dict().items()
                                          if v is not None))
    for path, why in ((tmp_path / "grey.npy", "no colour filter mosaic"), (tmp_path / "mono.npz", "monochrome"),
                      (tmp_path / "rgb.tif", "holds 3 colour channels per pixel")):
        assert main(["temperature", str(path), "--calibration", str(d["cal"]), "--camera", str(cam),
                     "--out", str(tmp_path / "t.h5")]) == 2
        assert why in capsys.readouterr().err
    assert not (tmp_path / "t.h5").exists()
    assert main(["calibrate-temperature", str(tmp_path / "rgb.tif"), "--temperature", "2000", "--out",
                 str(tmp_path / "bb.json")]) == 2
    assert "holds 3 colour channels per pixel" in capsys.readouterr().err


COLOUR_FILE = """[main_lens]
focal_length_mm = 100.0
f_number = 10.0
focus_distance_mm = 200.0

[microlens_array]
pitch_um = 150.0
focal_length_mm = 3.0

[sensor]
pixel_size_um = 12.6875      # lenslet images 150 um x (1 + 3/200) / 12.6875 um = 12 px apart
rows = 144
cols = 120
"""


def test_blackbody_images_that_store_no_camera_take_the_camera_file(tmp_path, capsys):
    """calibrate-temperature --camera cam.toml: raw blackbody images that store no camera (.npy, a TIFF from the
    camera) of a perfect-grid camera are calibrated with that file's grid and CFA, as temperature takes it; without
    it they are the paper camera's and refused (calibrate-temperature had no --camera)."""
    cam = tmp_path / "cam.toml"
    cam.write_text(COLOUR_FILE + 'cfa = "GRBG"\n')
    npys = []
    for t in (1600, 2400):
        assert main(["simulate", "--camera", str(cam), "--scene", "furnace", "--temperature", str(t),
                     "--rays-per-pixel", "2", "--out", str(tmp_path / f"bb{t}.npz")]) == 0
        npys.append(str(tmp_path / f"bb{t}.npy"))
        np.save(npys[-1], np.load(tmp_path / f"bb{t}.npz")["raw"])
    temps = ["--temperature", "1600", "--temperature", "2400"]
    assert main(["calibrate-temperature", *npys, *temps, "--out", str(tmp_path / "x.json")]) == 2
    capsys.readouterr()
    assert main(["calibrate-temperature", *npys, *temps, "--camera", str(cam), "--out", str(tmp_path / "a.json")]) == 0
    assert main(["calibrate-temperature", *[n.replace(".npy", ".npz") for n in npys], *temps,
                 "--out", str(tmp_path / "b.json")]) == 0
    a, b = (json.loads((tmp_path / f"{k}.json").read_text()) for k in "ab")
    assert a["pattern"] == "GRBG" and a["gain_ratio"] == pytest.approx(b["gain_ratio"], rel=1e-9)


def test_planes_of_a_real_grids_capture_are_not_flagged_cfa_blind():
    """The rule of CFA-blind planes (slopes near an odd integer) holds where the CFA's phase alternates with the
    lenslets, a perfect grid of odd N; a capture of a real grid (the example camera: 10.57 px, rotated) shifts it
    irregularly, and its planes at slopes 0.83 and 1.04 had been flagged though every lenslet saw red."""
    import types
    from pathlib import Path
    from lf_flame.cli.temperature_planes import _blind
    from lf_flame.optics.camera_file import load_camera_file
    real = load_camera_file(str(Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml"))
    slopes = [0.0, 0.83, 1.04]
    for lf, want in ((types.SimpleNamespace(decoded=True, capture_camera=real), [False] * 3),
                     (types.SimpleNamespace(decoded=False, capture_camera=None), [False, True, True]),
                     (types.SimpleNamespace(decoded=True, capture_camera=CAM), [False, True, True])):
        assert list(_blind(lf, slopes, 9)) == want            # 9 views, as the user's camera decodes to


def test_a_camera_file_names_its_colour_filter_array(tmp_path):
    """[sensor] cfa, cfa_phase and sensitivities make the file's colour sensor; a file without them is monochrome;
    bad values are refused naming the key. Whole-pixel lenslet images tiling the sensor are a perfect grid (no
    decoding), even where the pitch's float arithmetic lands a hair below 12 px."""
    from lf_flame.optics.camera_file import load_camera_file, load_colour_sensor
    mono = tmp_path / "mono.toml"
    mono.write_text(COLOUR_FILE)
    assert load_colour_sensor(mono) is None
    cam = load_camera_file(mono)
    assert cam.perfect_grid and cam.pixels_per_lenslet == 12 and (cam.n_rows, cam.n_cols) == (12, 10)
    colour = tmp_path / "colour.toml"
    colour.write_text(COLOUR_FILE + 'cfa = "BGGR"\ncfa_phase = [1, 0]\nsensitivities = "Sigma SDMerill (NPL)"\n')
    s = load_colour_sensor(colour)
    assert (s.name, s.pattern, s.phase) == ("Sigma SDMerill (NPL)", "BGGR", (1, 0))
    for extra, key in (('cfa = "RGBX"\n', "cfa must be one of"), ('cfa = "RGGB"\ncfa_phase = [2, 0]\n', "cfa_phase"),
                       ("cfa_phase = [0, 1]\n", "give cfa too"), ('cfa = "RGGB"\nsensitivities = "Nope"\n', "Nope")):
        bad = tmp_path / "bad.toml"
        bad.write_text(COLOUR_FILE + extra)
        with pytest.raises(ValueError, match=key):
            load_camera_file(bad)
    # a capture recording another CFA than the camera file names: the file's is used, with a warning naming both
    import warnings as w
    from lf_flame.real.readers import capture_sensor
    record = {"sensor": json.dumps(dict(name="Nikon 5100", pattern="RGGB", phase=[0, 0]))}
    with pytest.warns(UserWarning, match=r"records its colour filter array as RGGB phase \(0, 0\), the camera "
                                         r"file .* names BGGR phase \(1, 0\)"):
        assert capture_sensor(str(colour), record)[0].pattern == "BGGR"
    with w.catch_warnings():                 # the same layout, as spelt or otherwise (BGGR from its second row: GRBG)
        w.simplefilter("error", UserWarning)
        for pattern, phase in (("BGGR", [1, 0]), ("GRBG", [0, 0])):
            same = {"sensor": json.dumps(dict(name="x", pattern=pattern, phase=phase))}
            assert capture_sensor(str(colour), same)[0].pattern == "BGGR"
        assert capture_sensor(str(colour), {})[0]


def test_simulate_renders_colour_scenes_of_any_camera_file(tmp_path, capsys):
    """``simulate --camera FILE --scene furnace|colour-depth`` mosaics with the file's CFA and stores its sensor:
    on a blackbody each channel's pixels hold that channel's band integral (a mosaic of another phase would put
    blue where red is); a furnace without its temperature is refused."""
    from lf_flame.optics.colour import CHANNELS, cfa_channels
    from lf_flame.simulate.scenes_temperature import blackbody_channels
    cam_file = tmp_path / "colour.toml"
    cam_file.write_text(COLOUR_FILE + 'cfa = "BGGR"\n')
    out = tmp_path / "furnace.npz"
    assert main(["simulate", "--camera", str(cam_file), "--scene", "furnace", "--temperature", "2000",
                 "--rays-per-pixel", "4", "--out", str(out)]) == 0
    z = np.load(out)
    rec = json.loads(str(z["sensor"]))
    assert (rec["pattern"], rec["phase"]) == ("BGGR", [0, 0])
    raw = z["raw"]
    chan = cfa_channels(raw.shape, "BGGR", (0, 0))
    rr, cc = np.indices(raw.shape) % 12
    lit = (rr >= 4) & (rr < 8) & (cc >= 4) & (cc < 8)                  # each lenslet image's centre: all channels
    means = np.array([raw[(chan == c) & lit].mean() for c in range(3)])
    want = blackbody_channels(library_sensor(rec["name"], "BGGR", (0, 0)), 2000.0)
    assert np.allclose(means[0] / means[1], want[0] / want[1], rtol=0.03), (means, want, CHANNELS)
    assert np.allclose(means[2] / means[1], want[2] / want[1], rtol=0.03)
    flames = tmp_path / "flames.npz"
    assert main(["simulate", "--camera", str(cam_file), "--scene", "colour-depth", "--seed", "1",
                 "--rays-per-pixel", "2", "--out", str(flames)]) == 0
    objects = json.loads(str(np.load(flames)["objects"]))
    assert objects and all(1800 <= o["peak_k"] <= 2200 for o in objects)
    capsys.readouterr()
    assert main(["simulate", "--scene", "furnace", "--out", str(tmp_path / "f.npz")]) == 2
    assert "--temperature" in capsys.readouterr().err


def test_simulate_sequence_renders_a_colour_recording_that_temperature_and_sequence_read(tmp_path, capsys):
    """``simulate-sequence --colour`` renders each frame's flames with their temperature through the camera file's
    CFA at one exposure (the first frame's: a camera's is fixed over a recording), records the sensor and each
    flame's sheath temperature per frame; ``temperature`` gives every frame its planes' temperatures and
    ``sequence`` levels its frames' channels, where a recording rendered without --colour is monochrome."""
    from lf_flame.simulate.scenes_temperature import FLICKER_K, colour_flicker_frame, flicker_peaks
    from lf_flame.simulate.scenes_time import FlameSequence
    cam_file = tmp_path / "colour.toml"
    cam_file.write_text(COLOUR_FILE + 'cfa = "GRBG"\n')
    rec = tmp_path / "rec.h5"
    assert main(["simulate-sequence", "--camera", str(cam_file), "--colour", "--fps", "100", "--duration", "0.04",
                 "--rays-per-pixel", "2", "--quiet", "--out", str(rec)]) == 0
    with h5py.File(rec) as f:
        frames, truth = f["frames"][...], f["sheath_temperature_k"][...]
        sensor_rec = json.loads(f.attrs["sensor"])
        seq = FlameSequence.from_dict(json.loads(f.attrs["sequence"]))
        cam = PlenopticCamera.from_dict(json.loads(f.attrs["camera"]))
    assert sensor_rec["pattern"] == "GRBG" and frames.shape[0] == truth.shape[0] == 4
    peaks = np.array(flicker_peaks(len(seq.flames)))
    assert truth.shape[1] == len(seq.flames) and np.all(np.abs(truth - peaks) <= FLICKER_K + 1e-9)
    assert np.ptp(truth, axis=0).min() > 1.0                            # each sheath flickers
    sensor = library_sensor(sensor_rec["name"], "GRBG", (0, 0))
    exposure = colour_flicker_frame(seq, cam, sensor, 0, peaks_k=peaks).exposure
    cs = colour_flicker_frame(seq, cam, sensor, 3, peaks_k=peaks, exposure=exposure)
    assert [o["peak_k"] for o in cs.scene.objects] == pytest.approx(truth[3])
    raw = render_colour(cam, cs.scene, cs.channel_radiance, sensor, 2, (seq.seed * 1_000_003 + 3) % 2**63)
    assert np.array_equal(frames[3], np.round(np.clip(raw, 0, 1) * 65535).astype(np.uint16))
    bb = []
    for t in (1600, 2000, 2400):
        bb.append(str(tmp_path / f"bb{t}.npz"))
        assert main(["simulate", "--camera", str(cam_file), "--scene", "furnace", "--temperature", str(t),
                     "--rays-per-pixel", "2", "--out", bb[-1]]) == 0
    cal = str(tmp_path / "bb.json")
    assert main(["calibrate-temperature", *bb, *[x for t in (1600, 2000, 2400) for x in ("--temperature", str(t))],
                 "--out", cal]) == 0
    out = tmp_path / "T.h5"
    assert main(["temperature", str(rec), "--calibration", cal, "--route", "admm-cfa", "--depth", "0",
                 "--no-figure", "--out", str(out)]) == 0
    with h5py.File(out) as f:
        t = f["temperature_k"][...]
    assert t.shape[:2] == (4, 1) and np.isfinite(t).any(axis=(1, 2, 3)).all()
    # --depths scene: the recording's flames' depths (a simulated recording stores them, as sequence reads them)
    assert main(["temperature", str(rec), "--calibration", cal, "--route", "admm-cfa", "--depths", "scene",
                 "--no-figure", "--out", str(out)]) == 0
    with h5py.File(out) as f:
        assert np.allclose(f["depths_mm"][...], [fl.depth_offset_mm for fl in seq.flames])
    # a frame with a NaN pixel and a black one: rows with their failure, the other frames' temperatures as before
    # (the whole command had stopped on the first such frame, with nothing written)
    bad = tmp_path / "bad.h5"
    with h5py.File(rec) as f, h5py.File(bad, "w") as g:
        fr = f["frames"][...].astype(np.float32) / 65535
        fr[1, 5, 5], fr[2] = np.nan, 0.0
        g["frames"] = fr
        g.attrs.update(dict(f.attrs))
    capsys.readouterr()
    assert main(["temperature", str(bad), "--calibration", cal, "--route", "admm-cfa", "--depth", "0",
                 "--no-figure", "--out", str(tmp_path / "bad_T.h5")]) == 0
    assert "2 of 4 frames have no temperature" in capsys.readouterr().err
    df = pd.read_csv(tmp_path / "bad_T.csv", keep_default_na=False)
    assert (df.failure != "").tolist() == [False, True, True, False]
    with h5py.File(tmp_path / "bad_T.h5") as f:
        tb = f["temperature_k"][...]
    assert np.isnan(tb[1:3]).all()
    np.testing.assert_allclose(tb[[0, 3]], t[[0, 3]], rtol=1e-3, atol=1.0)
    capsys.readouterr()
    assert main(["sequence", str(rec), "--quiet", "--out", str(tmp_path / "seq")]) == 0
    assert "levelled into one light field" in capsys.readouterr().out


@pytest.mark.parametrize("layout", ["square", "hex"])
def test_a_colour_capture_of_any_grid_decodes_with_its_channels_apart(tmp_path, capsys, layout):
    """The example camera (10.57 px lenslet images, rotated 0.4°) with an RGGB CFA, on a square and on a hexagonal
    grid, from the command line: white image (a mosaic too) -> calibrate; blackbodies decoded with their channels
    apart -> calibrate-temperature; a blackbody at 1800 K decoded -> temperature (emissivity exponent 0): 1800 K
    within 15 K over the field, the same from the raw capture decoded with --grid-calibration. Each decoded sample
    keeps its nearest pixel's channel (a hexagonal grid's: on its
    lattice, where its channels are solved); decoded views without channels are refused; reconstruct levels the
    channels into one light field."""
    from pathlib import Path

    from lf_flame.real.calibration import GridCalibration
    from lf_flame.real.view_grid import view_positions
    from lf_flame.real.views_file import load_channels
    from lf_flame.optics.colour import cfa_channels
    example = (Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
    cam_file = tmp_path / "colour.toml"
    example = example.replace('layout = "square"', f'layout = "{layout}"')
    cam_file.write_text(example + 'cfa = "RGGB"\n')
    d = str(tmp_path)

    def run(*argv):
        assert main([str(x) for x in argv]) == 0, capsys.readouterr().err

    run("simulate", "--camera", cam_file, "--scene", "white", "--rays-per-pixel", 8, "--out", f"{d}/white.npz")
    assert json.loads(str(np.load(f"{d}/white.npz")["sensor"]))["pattern"] == "RGGB"      # rendered through the CFA
    run("calibrate", f"{d}/white.npz", "--out", f"{d}/cal.json")
    if layout == "hex":     # the mosaic's two-pixel period passes for the hexagonal lattice unless levelled
        np.savez(f"{d}/bare.npz", raw=np.load(f"{d}/white.npz")["raw"])
        capsys.readouterr()
        assert main(["calibrate", f"{d}/bare.npz", "--out", f"{d}/bare.json"]) == 2
        assert "give its camera file" in capsys.readouterr().err
        run("calibrate", f"{d}/bare.npz", "--camera", cam_file, "--out", f"{d}/bare.json")
    for t in (1600, 1800, 2400):
        run("simulate", "--camera", cam_file, "--scene", "furnace", "--temperature", t, "--rays-per-pixel", 4,
            "--out", f"{d}/bb{t}.npz")
        run("decode", f"{d}/bb{t}.npz", "--calibration", f"{d}/cal.json", "--camera", cam_file, "--out", f"{d}/bb{t}.h5")
    capsys.readouterr()                     # the raw images themselves: refused, naming the decoding they need
    assert main(["calibrate-temperature", f"{d}/bb1600.npz", f"{d}/bb2400.npz", "--temperature", "1600",
                 "--temperature", "2400", "--out", f"{d}/raw_bb.json"]) == 2
    assert "decode it first" in capsys.readouterr().err and not (tmp_path / "raw_bb.json").exists()
    run("calibrate-temperature", f"{d}/bb1600.h5", f"{d}/bb2400.h5", "--temperature", 1600, "--temperature", 2400,
        "--out", f"{d}/bb.json")
    cal = GridCalibration.load(f"{d}/cal.json")
    assert cal.layout == layout and abs(cal.pitch_px / (150 / 14.4 * (1 + 3 / 200)) - 1) < 5e-4
    chan = load_channels(f"{d}/bb1800.h5")
    q = np.floor(view_positions(cal, chan.shape[0])).astype(int)                 # the pixel each sample lies in
    assert np.array_equal(chan, cfa_channels(cal.sensor_shape, "RGGB", (0, 0))[q[..., 0], q[..., 1]])
    run("temperature", f"{d}/bb1800.h5", "--camera", cam_file, "--calibration", f"{d}/bb.json", "--depth", 0,
        "--alpha", 0, "--out", f"{d}/t.h5")
    assert "furnace image" not in capsys.readouterr().err
    # decoded views carry their channel map: a CFA given now cannot move it (it had been printed as the sensor, and
    # the data read with the stored map all the same)
    assert main(["temperature", f"{d}/bb1800.h5", "--camera", str(cam_file), "--calibration", f"{d}/bb.json",
                 "--depth", "0", "--cfa-phase", "1", "0", "--no-figure", "--out", f"{d}/t_phase.h5"]) == 2
    assert "--cfa and --cfa-phase cannot move the channel map" in capsys.readouterr().err
    # soot's emissivity exponent (the default) on a blackbody: a note, for the raw image and the views decoded from it
    from lf_flame.cli.temperature_planes import furnace_note
    assert furnace_note(f"{d}/bb1800.h5", 1.39) and furnace_note(f"{d}/bb1800.npz", 1.39)
    assert "give --alpha 0" in capsys.readouterr().err
    assert not furnace_note(f"{d}/white.npz", 1.39) and not furnace_note(f"{d}/bb1800.h5", 0.0)
    with h5py.File(f"{d}/t.h5") as f:
        t = f["temperature_k"][0][f["valid"][0]]
        settings = json.loads(f.attrs["route_settings"])
        assert ("lattice" in settings) == (layout == "hex")
        # not the noise's knobs; at focus the samples' offsets do not matter: whole views' knobs on either grid
        assert settings["regime"] == "decoded" and settings["knobs"] == DECODED_KNOBS
    assert t.size > 0.5 * cal.n_rows * cal.n_cols
    assert abs(np.median(t) - 1800) < 15 and np.percentile(np.abs(t - 1800), 90) < 30
    if layout == "hex":     # refocus-cfa refused on the lattice before any depth search, not after it
        capsys.readouterr()
        assert main(["temperature", f"{d}/bb1800.h5", "--camera", str(cam_file), "--calibration", f"{d}/bb.json",
                     "--route", "refocus-cfa", "--out", f"{d}/t_ref.h5"]) == 2
        printed = capsys.readouterr()
        assert "refocus-cfa refocuses a square grid's views" in printed.err and "found" not in printed.out
    # the raw capture with the grid's calibration: decoded here as decode decodes it, the same temperatures
    run("temperature", f"{d}/bb1800.npz", "--camera", cam_file, "--calibration", f"{d}/bb.json", "--grid-calibration",
        f"{d}/cal.json", "--depth", 0, "--alpha", 0, "--out", f"{d}/t_raw.h5")
    with h5py.File(f"{d}/t.h5") as f, h5py.File(f"{d}/t_raw.h5") as g:
        assert np.array_equal(f["temperature_k"][:], g["temperature_k"][:], equal_nan=True)
    # a recording of such raw frames (a folder): each frame decoded so, the same temperatures frame by frame
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(2):
        np.save(frames / f"f{i}.npy", np.load(f"{d}/bb1800.npz")["raw"])
    run("temperature", frames, "--camera", cam_file, "--calibration", f"{d}/bb.json", "--grid-calibration",
        f"{d}/cal.json", "--depth", 0, "--alpha", 0, "--fps", 10, "--no-figure", "--out", f"{d}/t_rec.h5")
    with h5py.File(f"{d}/t_raw.h5") as f, h5py.File(f"{d}/t_rec.h5") as g:
        assert g["temperature_k"].shape == (2,) + f["temperature_k"].shape
        for k in range(2):
            np.testing.assert_allclose(g["temperature_k"][k], f["temperature_k"][:], rtol=1e-5, equal_nan=True)
    # the emission routes level the channels into one light field: the blackbody is then one grey plane (a mosaic
    # fitted as it is leaves 0.44 of it unexplained, at this test's 4 rays per pixel 0.13 levelled)
    from lf_flame.tomo.files import load_reconstruction
    run("reconstruct", f"{d}/bb1800.h5", "--camera", cam_file, "--depth", 0, "--out", f"{d}/r.h5")
    assert load_reconstruction(f"{d}/r.h5").residuals[-1] < 0.2
    with h5py.File(f"{d}/r.h5") as f:
        assert "levelled" in f.attrs["monochrome"]
    mono_file = tmp_path / "mono.toml"                                   # the same camera, monochrome
    mono_file.write_text(example)
    run("simulate", "--camera", mono_file, "--scene", "white", "--rays-per-pixel", 4, "--out", f"{d}/mono.npz")
    run("decode", f"{d}/mono.npz", "--calibration", f"{d}/cal.json", "--out", f"{d}/mono.h5")
    capsys.readouterr()
    assert main(["temperature", f"{d}/mono.h5", "--camera", str(cam_file), "--calibration", f"{d}/bb.json",
                 "--depth", "0", "--out", f"{d}/t2.h5"]) == 2
    assert "without their colour channels" in capsys.readouterr().err
    # a monochrome capture with no record of its sensor decoded with the colour camera file: refused (decoded, every
    # temperature would read one ratio); the simulated one records that it is monochrome, and is decoded so
    np.save(f"{d}/mono.npy", np.load(f"{d}/mono.npz")["raw"])
    assert main(["decode", f"{d}/mono.npy", "--calibration", f"{d}/cal.json", "--camera", str(cam_file),
                 "--out", f"{d}/mono_as_colour.h5"]) == 2
    assert "holds no colour filter mosaic" in capsys.readouterr().err and not (tmp_path / "mono_as_colour.h5").exists()


def test_a_colour_captures_emission_is_solved_at_each_samples_own_pixel(tmp_path, colour_capture):
    """A square colour capture's samples are each its nearest pixel, up to half a view step from the view's place;
    the exact operator with those offsets (``LightField.sample_offsets``, three sub-views per view and axis) fits the
    decoded views and recovers the flames' emission better than the operator that puts every sample at its view's
    place: colour flames of ``simulate --scene colour-depth`` through the example camera with an RGGB CFA, noise-free,
    solved at their true depths (the levelled light field, admm on the 2 x 2 grid), each plane scored against the
    green channel's emission in the decoded frame."""
    import dataclasses

    from lf_flame.cli._io import colour_scene
    from lf_flame.real.readers import read_light_field
    from lf_flame.temperature.mosaic import monochrome_light_field
    from lf_flame.tomo.decoded import decoded_plane_truth, fit_data
    from lf_flame.tomo.exact import ExactOperator
    from lf_flame.tomo.solvers import reconstruct
    cam_file = colour_capture(7, 32)
    lf = read_light_field(tmp_path / "scene.h5", str(cam_file))
    assert lf.sample_offsets is not None and np.abs(lf.sample_offsets).max() > 0.45
    scene, chans, _ = colour_scene(json.loads(str(np.load(tmp_path / "scene.npz")["scene"])), lf.capture_camera)
    depths = sorted({round(L.depth_offset_mm, 6) for L in scene.layers})
    assert max(abs(lf.camera.slope_for_depth(z)) for z in depths) > 0.3            # parallax the offsets matter at
    R, C = lf.views.shape[2:]
    truth = np.zeros((len(depths), R, C))
    for L, ch in zip(scene.layers, chans):
        z = round(L.depth_offset_mm, 6)
        truth[depths.index(z)] += decoded_plane_truth(dataclasses.replace(L, radiance=ch[1]), lf.camera, z, (R, C),
                                                      lf.frame.rotation_deg, lf.frame.centre_lenslets)
    mono = monochrome_light_field(lf)
    scores = {}
    for name, offsets in (("own pixel", lf.sample_offsets), ("view's place", None)):
        op = ExactOperator(lf.camera, depths, precision="float32", subsamples=2, sample_offsets=offsets)
        data, leave = fit_data(mono, op)
        rec = reconstruct(data, op, "admm", saturation=leave)
        assert rec.settings.get("sub_views") == (None if offsets is None else 3)
        planes = rec.planes.reshape(len(depths), R, 2, C, 2).mean((2, 4))
        fitted = ~leave
        res = op.matvec(np.repeat(np.repeat(planes, 2, 1), 2, 2).ravel()).reshape(op.dimsd) - data
        scores[name] = (max(np.linalg.norm(p - t) / np.linalg.norm(t) for p, t in zip(planes, truth)),
                        np.linalg.norm(res[fitted]) / np.linalg.norm(data[fitted]))
    assert scores["own pixel"][0] < 0.7 * scores["view's place"][0]
    assert scores["own pixel"][1] < 0.9 * scores["view's place"][1]


def test_a_raw_colour_capture_decoded_on_the_fly_keeps_its_channels_apart(tmp_path, colour_capture, capsys):
    """A raw colour capture given with its calibration (decoded on the fly, as reconstruct, refocus, slopes and
    profiles read it) is decoded as ``lf-flame decode --camera`` decodes it: each sample its nearest pixel, the
    channel map and sample offsets with it (it was decoded as a monochrome capture, bilinear sampling blending
    red, green and blue), from the camera file's CFA or the sensor the image stores; reconstruct says how many
    samples it left out of the views' and why (the blue ones among them)."""
    from lf_flame.cli._io import _raw_reader
    from lf_flame.real.readers import read_light_field
    cam_file = colour_capture(3, 4)
    decoded = read_light_field(tmp_path / "scene.h5", str(cam_file))
    for camera in (str(cam_file), None):                   # the file's [sensor], else the image's stored record
        here = read_light_field(tmp_path / "scene.npz", camera or decoded.capture_camera, tmp_path / "cal.json",
                                raw_reader=_raw_reader)
        assert here.channels is not None and np.array_equal(here.channels, decoded.channels)
        assert np.allclose(here.views, decoded.views, atol=1e-6)
        assert np.array_equal(here.sample_offsets, decoded.sample_offsets) and "sensor" in here.meta
    capsys.readouterr()
    assert main(["reconstruct", str(tmp_path / "scene.npz"), "--camera", str(cam_file), "--calibration",
                 str(tmp_path / "cal.json"), "--depth", "0", "--out", str(tmp_path / "r.h5")]) == 0
    note = next(line for line in capsys.readouterr().out.splitlines() if "left out of the fit (clipped" in line)
    n, total = (int(v) for v in note.split(" samples")[0].split(" of "))
    assert total == decoded.views.size and 0.25 < n / total < 0.6 and "blue samples" in note


def test_a_raw_images_sensor_is_the_one_its_camera_file_decodes_it_with(files, tmp_path):
    """temperature reads a raw image through its camera file's colour filter array (as decoding does), so a camera
    file naming GRBG against an RGGB calibration is refused (the frame was decoded as GRBG while the pyrometer took
    the calibration's RGGB: 2,717 K for 1,863 K); a recording's frame (RECORDING.h5:INDEX) reports the sensor its
    recording stores (it said it records none)."""
    import argparse
    from pathlib import Path

    from lf_flame.cli.temperature_planes import _sensor
    from lf_flame.temperature.pyrometry import load_calibration
    root = Path(__file__).resolve().parents[1]
    grbg = tmp_path / "grbg.toml"
    grbg.write_text((root / "examples" / "colour_camera.toml").read_text().replace('cfa = "RGGB"', 'cfa = "GRBG"'))
    a = argparse.Namespace(camera=str(grbg), sensor=None, cfa=None, cfa_phase=None)
    cal = load_calibration(files["cal"])
    sensor, where = _sensor(files["flame"], a, cal)
    assert sensor.pattern == "GRBG" and where == f"{grbg} [sensor]"
    with pytest.raises(ValueError, match="made for sensor .* CFA RGGB .* the images are from .* CFA GRBG"):
        cal.check_sensor(sensor)
    a.camera = None
    assert _sensor(files["flame"], a, cal)[1] == f"stored in {files['flame']}"      # without one: the image's record
    rec = tmp_path / "rec.h5"
    with h5py.File(rec, "w") as f:
        f["frames"] = np.zeros((2, 4, 4), np.float32)
        f.attrs["sensor"] = json.dumps(files["sensor"].record())
    sensor, where = _sensor(f"{rec}:1", a, cal)
    assert where == f"stored in {rec}:1" and sensor.pattern == files["sensor"].pattern
