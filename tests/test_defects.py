"""A sensor's defective pixels (lf_flame.real.defects): found against their neighbours in the light field, repaired
for the depth search and refocusing, and left out of the fit."""
import numpy as np
import pytest
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
