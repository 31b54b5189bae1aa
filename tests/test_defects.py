"""A sensor's defective pixels (lf_flame.real.defects): found against their neighbours in the light field, repaired
for the depth search and refocusing, and left out of the fit."""
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import ndimage

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.real.defects import defective_pixels, lenslet_offsets
from lf_flame.real.lightfield import from_raw
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate import tracer
from lf_flame.simulate.scenes_depth import random_depth_scene
from lf_flame.tomo.depth import find_depths


@pytest.fixture(scope="module")
def cam():
    return PlenopticCamera(n_rows=60, n_cols=40)


@pytest.fixture(scope="module")
def capture(cam):
    """Two flames at random depths (their depths), the clean raw image, and the same with 1 pixel in 100 defective:
    half hot (0.3-1 of the clipping level), half dead (0), and where they are."""
    scene = random_depth_scene(cam, np.random.default_rng(7), n_flames=2, height_range=(2.0, 5.0))
    raw = tracer.render(cam, scene, 32, 7)
    rng = np.random.default_rng(1)
    idx = rng.choice(raw.size, raw.size // 100, replace=False)
    hot, dead = idx[: len(idx) // 2], idx[len(idx) // 2:]
    bad = raw.copy()
    bad.flat[hot] = np.maximum(bad.flat[hot], rng.uniform(0.3, 1.0, len(hot)))
    bad.flat[dead] = 0.0
    where = np.zeros(raw.shape, bool)
    where.flat[idx] = bad.flat[idx] != raw.flat[idx]
    return sorted(o["depth_offset_mm"] for o in scene.objects), raw, bad, where


def test_defective_pixels_are_found_and_nothing_else(cam, capture):
    _, raw, bad, where = capture
    off = lenslet_offsets(cam.pixels_per_lenslet * np.eye(2))
    flagged, repaired = defective_pixels(raw, off)
    assert not flagged.any() and np.array_equal(repaired, raw)            # a clean render: no pixel taken
    flagged, repaired = defective_pixels(bad, off)
    assert not (flagged & ~where).any()                                   # only defects
    peak = np.percentile(raw, 99.9)
    big = where & (np.abs(bad - raw) > 0.2 * peak)
    n = 2 * cam.pixels_per_lenslet + 1                # off the flames, where they would be read as flames
    dark = big & (ndimage.maximum_filter(raw, n) < 0.05 * peak)
    assert dark.sum() > 100 and flagged[dark].mean() > 0.95    # but where another stands under a lenslet around
    assert (flagged & big).sum() >= 0.8 * big.sum()  # on the flames' edges some stay within their neighbours' range
    err = np.abs(repaired - raw)[flagged]                                  # the repair: its neighbours' median
    assert np.median(err) < 0.01 * peak and err.max() < 0.25 * peak
    assert np.array_equal(repaired[~flagged], bad[~flagged])


def test_defects_are_not_flames(cam, capture):
    """Read as they are, the defects are found as flames of their own; the light field of the image repairs them
    and leaves their samples out of the fit."""
    depths, raw, bad, where = capture
    n = cam.pixels_per_lenslet
    assert len(find_depths(raw_to_views(bad, n), cam).depths_mm) > len(depths)
    lf = from_raw(bad, cam)
    found = find_depths(lf.views, cam).depths_mm
    np.testing.assert_allclose(found, find_depths(raw_to_views(raw, n), cam).depths_mm, atol=0.05)
    np.testing.assert_allclose(found, depths, atol=0.3)
    assert lf.defective_pixels == int(defective_pixels(bad, lenslet_offsets(n * np.eye(2)))[0].sum())
    assert lf.saturation == 1.0 and lf.leave_out is None and not (lf.defects & ~(raw_to_views(where, n) > 0)).any()
    assert lf.defects.sum() == lf.defective_pixels and np.array_equal(lf.fit_mask(), lf.defects | (lf.views >= 1.0))
    clean = from_raw(raw, cam)
    assert clean.defective_pixels == 0 and clean.defects is None and clean.fit_mask() == 1.0


def test_cli_reconstruct_reports_and_leaves_out_the_defects(cam, capture, tmp_path, capsys):
    import h5py

    from lf_flame.cli import main
    depths, _, bad, _ = capture
    raw = tmp_path / "bad.npz"
    np.savez(raw, raw=bad, camera=cam.to_json())
    assert main(["reconstruct", str(raw), "--out", str(tmp_path / "r.h5")]) == 0
    out = capsys.readouterr().out
    assert "found 2 depths" in out and "defective pixels (hot or dead" in out
    with h5py.File(tmp_path / "r.h5") as f:
        np.testing.assert_allclose(sorted(f["depths_mm"][...]), depths, atol=0.3)


def test_neighbours_and_refusals():
    off = lenslet_offsets(15 * np.eye(2))
    assert len(off) == 16 and len({tuple(o) for o in off}) == 16
    assert {(15, 0), (0, -15), (15, 15), (-15, 15)} <= {tuple(o) for o in off}
    colour = lenslet_offsets(10.57 * np.eye(2), step=2)                   # a Bayer mosaic: pixels of one colour
    assert np.all(colour % 2 == 0) and {(10, 0), (0, 10), (2, 2)} <= {tuple(o) for o in colour}
    # a step that rounds to even pixels 0.96 px off its place (another view) is taken twice: 21.92 -> 22 px
    wide = {tuple(o) for o in lenslet_offsets(10.96 * np.eye(2), step=2)}
    assert {(22, 0), (0, -22), (22, 22)} <= wide and (10, 0) not in wide
    assert (11, 0) in {tuple(o) for o in lenslet_offsets(10.96 * np.eye(2))}            # monochrome: as before
    hexa = lenslet_offsets(10 * np.eye(2), "hex")
    assert {(0, 10), (9, 5), (9, -5), (17, 0)} <= {tuple(o) for o in hexa}
    img = np.zeros((30, 30))
    for bad, match in (((np.eye(3),), "2 x 2"), ((np.eye(2), "round"), "layout"), ((1.4 * np.eye(2),), "too close"),
                       ((np.eye(2) * 10, "square", 0), "step")):
        with pytest.raises(ValueError, match=match):
            lenslet_offsets(*bad)
    for kw, match in ((dict(margin=0.0), "margin"), (dict(spread=-1.0), "spread"), (dict(level=np.nan), "level")):
        with pytest.raises(ValueError, match=match):
            defective_pixels(img, off, **kw)
    with pytest.raises(ValueError, match="NaN"):
        defective_pixels(np.full((30, 30), np.nan), off)
    with pytest.raises(ValueError, match="offsets"):
        defective_pixels(img, off.astype(float))
    flagged, repaired = defective_pixels(img, off)                         # no light: nothing stands out of it
    assert not flagged.any() and np.array_equal(repaired, img)


def test_a_black_level_left_in_is_named_by_the_misfit_warning(cam, capture, tmp_path, capsys):
    """A sensor's offset left in the image (3 % of the clipping level) is light no plane explains: the misfit
    warning says that the samples no light reaches read it; the image as rendered gets no such note."""
    from lf_flame.cli import main
    _, raw, _, _ = capture
    for name, img in (("offset", raw + 0.03), ("clean", raw)):
        np.savez(tmp_path / f"{name}.npz", raw=img, camera=cam.to_json())
        assert main(["reconstruct", str(tmp_path / f"{name}.npz"), "--out", str(tmp_path / f"{name}.h5")]) == 0
        err = capsys.readouterr().err
        assert ("read 0.03," in err and "black level or stray light not subtracted" in err) == (name == "offset")
        assert name == "clean" or "warning: the planes leave" in err


def _counts(raw, gain, shift=0):
    """``raw`` times ``gain`` as a 12-bit sensor's counts in 16 bits (shifted to the top bits by ``shift`` 4)."""
    return np.round(np.clip(raw * gain, 0, 1) * 4095).astype(np.uint16) << shift


def test_the_clipping_level_is_found_where_the_pixels_pile_up(capture):
    """A 12-bit sensor's counts in a 16-bit file clip at 4095, or at 65520 shifted to the top bits: the level is
    found where the pixels pile up, as counts or scaled by the type's range (as the commands read image files);
    an image that does not clip keeps the type's level, and a few pixels at its top are no pile."""
    from skimage import util

    from lf_flame.real.clipping import PILE_MIN_PIXELS, auto_saturation, clipping_pile
    _, raw, _, _ = capture
    gain = 1.6 / raw.max()
    for shift in (0, 4):
        counts = _counts(raw, gain, shift)
        top = 4095 << shift
        assert 0.001 < np.mean(counts == top) < 0.05                   # the flames' cores clip
        assert auto_saturation(counts.astype(float)) == top
        assert auto_saturation(util.img_as_float64(counts)) == top / 65535
    dim = _counts(raw, 0.6 / raw.max())
    assert clipping_pile(dim) is None
    assert auto_saturation(dim.astype(float)) == 4095 and auto_saturation(util.img_as_float64(dim)) == 1.0
    few = dim.copy()
    few.flat[:PILE_MIN_PIXELS - 1] = 4000                               # hot pixels, fewer than a pile
    assert clipping_pile(few) is None
    few.flat[:PILE_MIN_PIXELS] = 4000
    assert clipping_pile(few) == 4000
    assert clipping_pile(np.full((9, 9), 7.0)) is None and clipping_pile(np.zeros((9, 9))) is None
    # an even field quantised to a few counts piles up at its top count: no clipping (10 of 4095 counts, 12 bits)
    even = np.full((200, 200), 10.0)
    even[::10], even[:, :20] = 9.0, 0.0                                  # some at the count below, a dark border
    even /= 4095
    assert np.mean(even == even.max()) > 0.5 and clipping_pile(even) is None and auto_saturation(even) == 1.0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 6), min_size=1, max_size=60), st.sampled_from([np.uint16, np.float32, np.float64]))
def test_the_two_largest_values_are_counted_in_one_pass(values, dtype):
    """The pile's kernel against NumPy: the largest value and its count, the next value below and its count (-inf
    and 0 where every pixel holds one value)."""
    from lf_flame.real._clipping_kernels import top_two
    a = np.asarray(values, dtype)
    top, n_top, second, n_second = top_two(a)
    below = a[a < a.max()]
    assert (top, n_top) == (float(a.max()), int(np.sum(a == a.max())))
    assert (second, n_second) == ((float(below.max()), int(np.sum(a == below.max()))) if below.size else (-np.inf, 0))


@pytest.mark.parametrize("top", [4095, 3600], ids=["12 bits", "full well below the top"])
def test_cli_leaves_out_the_pixels_of_a_16_bit_file_clipped_at_12_bits(cam, capture, tmp_path, capsys, top):
    """``reconstruct`` of a TIFF of 12-bit counts, clipped at 4095 or by a full well of 3600, leaves out the clipped
    pixels by the level found in it: the fit of the level given; the type's level (1.0, what was taken before)
    leaves none out and another fit."""
    import h5py
    import tifffile

    from lf_flame.cli import main
    _, raw, _, _ = capture
    counts = np.round(np.clip(raw * 1.6 / raw.max(), 0, 1) * top).astype(np.uint16)
    tifffile.imwrite(tmp_path / "c.tif", counts)
    (tmp_path / "cam.toml").write_text(f"[camera]\nn_rows = {cam.n_rows}\nn_cols = {cam.n_cols}\n")
    level = float(np.float32(top / 65535))                              # the views' float32 rounding of the level
    lf = from_raw(counts / 65535.0, cam, saturation=None)
    n_clipped = int(np.count_nonzero(lf.views >= level))
    planes = {}
    for name, extra in (("found", []), ("given", ["--saturation", repr(level)]), ("type", ["--saturation", "1"])):
        out = tmp_path / f"{name}.h5"
        assert main(["reconstruct", str(tmp_path / "c.tif"), "--camera", str(tmp_path / "cam.toml"), "--depths",
                     "paper", "--out", str(out)] + extra) == 0
        printed = capsys.readouterr().out
        n = n_clipped if name != "type" else 0
        assert f"{n} saturated pixels (at or above {level if name != 'type' else 1:g})" in printed
        with h5py.File(out) as f:
            planes[name] = f["planes"][...]
    np.testing.assert_array_equal(planes["found"], planes["given"])
    off = np.linalg.norm(planes["type"] - planes["given"]) / np.linalg.norm(planes["given"])
    assert n_clipped > 100 and off > 0.02


def test_a_recordings_frames_clipped_at_12_bits_leave_out_their_clipped_pixels(tmp_path):
    """A folder of 16-bit PNG frames holding 12-bit counts (the second shifted to the top bits): each frame's
    clipped pixels are left out of the fit by the level found in that frame, and nothing else but its defective
    pixels' samples."""
    from skimage import io

    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.recordings.job import simulated_job
    from lf_flame.recordings.sources import SimulatedSource, open_source
    from lf_flame.simulate.scenes_time import flicker_sequence
    seq = flicker_sequence(PAPER_CAMERA, np.random.default_rng(5), "overlap", fps=100, duration_s=0.02)
    raw = next(iter(SimulatedSource(seq, PAPER_CAMERA, 2).frames(0, 1)))
    for shift in (0, 4):
        io.imsave(tmp_path / f"f{shift}.png", _counts(raw, 1.6 / raw.max(), shift), check_contrast=False)
    src, _ = open_source(tmp_path)
    job = simulated_job(seq, PAPER_CAMERA, src, route="reconstruct-admm")[0]
    for frame, top in zip(src.frames(0, 2), (4095, 65520)):
        views, defects = job.frame(frame)
        data, leave = job.fit_data(views, defects)
        left = data >= leave if np.ndim(leave) == 0 else leave
        clipped = data == np.float32(top / 65535)
        assert clipped.sum() > 1000 and np.array_equal(left & clipped, clipped)
        assert not (left & ~clipped & (True if defects is None else ~defects)).any()


def test_an_over_exposed_capture_is_named_by_a_warning(cam, capture, tmp_path, capsys):
    """``reconstruct`` warns where more than ``CLIPPED_WARN`` of the lit pixels are clipped (the capture exposed so
    that a fifth of them clip) and records the share; the capture as rendered (none clipped) gets no warning."""
    import h5py

    from lf_flame.cli import main
    from lf_flame.real.clipping import CLIPPED_WARN
    _, raw, _, _ = capture
    for name, img in (("over", np.clip(raw * 1.6 / raw.max(), 0, 1)), ("as rendered", raw)):
        np.savez(tmp_path / "c.npz", raw=img, camera=cam.to_json())
        assert main(["reconstruct", str(tmp_path / "c.npz"), "--depths", "paper", "--out", str(tmp_path / "c.h5")]) == 0
        err = capsys.readouterr().err
        with h5py.File(tmp_path / "c.h5") as f:
            share = float(f.attrs["clipped_share"])
        assert ("of the lit pixels are clipped" in err) == (name == "over") == (share > CLIPPED_WARN)
        assert name != "over" or f"warning: {100 * share:.3g} % of the lit pixels" in err


def test_a_recordings_over_exposed_frames_are_counted_and_named(cam, capture, tmp_path, capsys):
    """``sequence`` on a reconstruction route measures each frame's clipped share (frames.csv), counts the frames
    beyond ``CLIPPED_WARN`` (summary.json) and warns of them: a stack of the capture as rendered and over-exposed."""
    import json

    import pandas as pd
    import tifffile

    from lf_flame.cli import main
    from lf_flame.real.clipping import CLIPPED_WARN, clipped_share
    _, raw, _, _ = capture
    frames = np.stack([raw, np.clip(raw * 1.6 / raw.max(), 0, 1)]).astype(np.float32)
    tifffile.imwrite(tmp_path / "rec.tif", frames, imagej=True, metadata={"finterval": 0.01})
    (tmp_path / "cam.toml").write_text(f"[camera]\nn_rows = {cam.n_rows}\nn_cols = {cam.n_cols}\n")
    assert main(["sequence", str(tmp_path / "rec.tif"), "--camera", str(tmp_path / "cam.toml"), "--depth", "0",
                 "--route", "reconstruct-admm", "--out", str(tmp_path / "out"), "--quiet"]) == 0
    share = pd.read_csv(tmp_path / "out" / "frames.csv").groupby("frame").clipped_share.first().to_numpy()
    np.testing.assert_allclose(share, [clipped_share(f, 1.0) for f in frames], rtol=1e-5)      # the CSV's digits
    assert share[0] < CLIPPED_WARN < share[1]
    over = json.loads((tmp_path / "out" / "summary.json").read_text())["over_exposed"]
    assert (over["frames"], over["clipped_frames"], over["max_share"]) == (1, 1, pytest.approx(share[1]))
    assert f"warning: in 1 of 2 frames up to {100 * share[1]:.3g} % of the lit pixels" in capsys.readouterr().err


def test_a_decoded_captures_over_exposure_is_measured_on_its_raw_pixels(tmp_path, capsys):
    """A capture of a camera that needs decoding, as 12-bit counts: ``decode`` stores the clipped share of its raw
    pixels (a decoded sample mixes several, so the views' clipped samples overstate it), and ``reconstruct`` warns
    with the same share from the views file and from the raw capture decoded on the fly."""
    import h5py
    import tifffile

    from lf_flame.cli import main
    from lf_flame.real.clipping import clipped_share
    cam = str(Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml")
    for scene in ("white", "depth"):
        assert main(["simulate", "--camera", cam, "--scene", scene, "--seed", "3", "--rays-per-pixel", "4",
                     "--out", str(tmp_path / f"{scene}.npz")]) == 0
    white, raw = (np.load(tmp_path / f"{s}.npz")["raw"] for s in ("white", "depth"))
    tifffile.imwrite(tmp_path / "white.tif", np.round(0.9 * white / white.max() * 4095).astype(np.uint16))
    counts = _counts(raw, 2.2 / raw.max())
    tifffile.imwrite(tmp_path / "c.tif", counts)
    assert main(["calibrate", str(tmp_path / "white.tif"), "--out", str(tmp_path / "cal.json")]) == 0
    capsys.readouterr()
    assert main(["decode", str(tmp_path / "c.tif"), "--calibration", str(tmp_path / "cal.json"), "--camera", cam,
                 "--out", str(tmp_path / "v.h5")]) == 0
    share = clipped_share(counts.astype(float), 4095)
    printed = capsys.readouterr()
    assert f"{100 * share:.3g} % of the lit pixels clipped" in printed.out
    assert f"warning: {100 * share:.3g} % of the lit pixels are clipped" in printed.err
    with h5py.File(tmp_path / "v.h5") as f:
        assert f.attrs["clipped_share"] == pytest.approx(share) and 0.08 < share < 0.5
        views_share = f["clipped"][...].sum() / np.count_nonzero(f["clipped"][...] | (f["views"][...] >= 0.05))
    capsys.readouterr()
    for source in ("v.h5", "c.tif"):
        out = tmp_path / f"r_{source.split('.')[0]}.h5"
        assert main(["reconstruct", str(tmp_path / source), "--camera", cam, "--calibration", str(tmp_path / "cal.json"),
                     "--out", str(out)]) == 0
        assert f"warning: {100 * share:.3g} % of the lit pixels are clipped" in capsys.readouterr().err
        with h5py.File(out) as f:
            assert float(f.attrs["clipped_share"]) == pytest.approx(share)
    assert views_share > 1.2 * share                          # what the views' own mask would have said
    from lf_flame.cli.real import overexposure_warning
    overexposure_warning(1.0)                                 # every lit pixel clipped: '100 %', not '1e+02 %'
    assert "warning: 100 % of the lit pixels are clipped" in capsys.readouterr().err


def test_a_colour_images_clipped_channel_is_found_in_its_gray_image(cam, capture, tmp_path, capsys):
    """An RGB file (a colour camera's demosaiced output) whose red channel clips: its gray image (the channels'
    mean) gives those pixels the clipping level, so that they pile up and are left out as clipped, by every reader
    (the command line's, the calibration's, a recording's frames); a plain mean has no pile there."""
    import tifffile

    from lf_flame.cli import main
    from lf_flame.real.clipping import auto_saturation, clipping_pile
    from lf_flame.real.images import load_image
    from lf_flame.real.images import frame_units as _scaled
    _, raw, _, _ = capture
    rgb = np.stack([_counts(raw, g / raw.max()) for g in (2.0, 0.8, 0.3)], axis=-1)
    red = rgb[..., 0] == 4095
    assert red.sum() > 100 and (rgb[..., 1:] < 4095).all()
    assert clipping_pile(rgb.mean(axis=-1)) is None                              # what the mean alone gives
    tifffile.imwrite(tmp_path / "rgb.tif", rgb)
    for gray, top in ((load_image(tmp_path / "rgb.tif"), 4095.0), (_scaled(rgb), np.float32(4095 / 65535))):
        assert auto_saturation(gray) == top and np.array_equal(gray >= top, red)
    (tmp_path / "cam.toml").write_text(f"[camera]\nn_rows = {cam.n_rows}\nn_cols = {cam.n_cols}\n")
    assert main(["reconstruct", str(tmp_path / "rgb.tif"), "--camera", str(tmp_path / "cam.toml"), "--depths",
                 "paper", "--out", str(tmp_path / "r.h5")]) == 0
    lf = from_raw(load_image(tmp_path / "rgb.tif") / 65535, cam)
    n = int(np.count_nonzero(lf.views >= lf.saturation))
    assert n <= red.sum() <= n + lf.defective_pixels                 # a clipped pixel may be taken for a defect too
    assert n > 100 and f"{n} saturated pixels" in capsys.readouterr().out


def test_cli_volume_leaves_out_the_defects_whatever_the_level(cam, capture, tmp_path):
    """``--volume`` with the level given (the file's own, 1.0) solves as it does by default: the defective pixels'
    samples stay out of the fit, as on the planes route."""
    import h5py

    from lf_flame.cli import main
    _, _, bad, _ = capture
    raw = tmp_path / "bad.npz"
    np.savez(raw, raw=bad, camera=cam.to_json())
    planes = {}
    for name, extra in (("default", []), ("given", ["--saturation", "1"])):
        out = tmp_path / f"{name}.h5"
        assert main(["reconstruct", str(raw), "--volume", "--from", "-4", "--to", "4", "--step", "2",
                     "--out", str(out), *extra]) == 0
        with h5py.File(out) as f:
            planes[name] = f["planes"][...]
    np.testing.assert_array_equal(planes["given"], planes["default"])


def test_a_capture_in_counts_with_defective_pixels_gives_its_planes_in_counts(cam, capture, tmp_path):
    """The capture's defective pixels make the fit a mask of samples; the clipping level found in the file stays the
    views' unit (``LightField.unit``), so the same noisy capture in 16-bit counts gives the planes of its [0, 1] file
    times 65535 (they were 25 % apart on a user's capture with 5 defective pixels: TV applied in counts)."""
    import h5py

    from lf_flame.cli import main
    depths, _, bad, _ = capture
    noisy = np.clip(bad + np.random.default_rng(4).normal(0.0, 0.03, bad.shape), 0.0, 1.0)
    counts = np.round(noisy * 65535).astype(np.uint16)
    planes = {}
    for name, raw in (("unit", (counts / 65535).astype(np.float32)), ("counts", counts)):
        path = tmp_path / f"{name}.npz"
        np.savez(path, raw=raw, camera=cam.to_json())
        out = tmp_path / f"{name}.h5"
        assert main(["reconstruct", str(path), *[f"--depth={d}" for d in depths], "--out", str(out),
                     "--no-figure"]) == 0
        with h5py.File(out) as f:
            planes[name] = f["planes"][...]
            assert json.loads(f.attrs["settings"])["tv"] > 0           # the noisy regime's TV: a weight with units
    rel = np.linalg.norm(planes["counts"] / 65535 - planes["unit"]) / np.linalg.norm(planes["unit"])
    assert rel < 1e-3, rel
