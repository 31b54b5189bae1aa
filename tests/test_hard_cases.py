"""Hard cases of docs/hard_cases.md not covered by the module tests: accumulation at high
ray counts, refocusing edge inputs, paraxial validity, training targets at the range
ends, determinism of whole datasets, disk full. Property tests use hypothesis."""
import errno
import os
import subprocess
import sys
import warnings

import h5py
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from lf_flame.learn import dataset as D
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA, PARAXIAL_LIMIT, PlenopticCamera
from lf_flame.config import DatasetConfig, atomic_write_text
from lf_flame.refocus.shift_and_sum import FourierSlice, aperture_mask, focal_stack, raw_to_views


# ---- accumulation -------------------------------------------------------------------
from lf_flame.refocus.slope_search import find_sharpest_slope, normalized_variance, tenengrad, variance_of_laplacian

def test_1e8_rays_into_one_pixel_lose_no_counts(uniform_scene):
    # a float32 running sum of 0.5s stalls at 2**24 (and would read ~0.08 here); the
    # kernel sums each pixel's rays in float64, exact for integers up to 2**53
    cam = PlenopticCamera(n_rows=1, n_cols=1, pixels_per_lenslet=1)
    raw = simulate.render(cam, uniform_scene(cam, 0.5), rays_per_pixel=100_000_000)
    assert raw.shape == (1, 1) and raw[0, 0] == 0.5


def test_full_sensor_at_high_ray_count_is_exact(uniform_scene):
    cam = PlenopticCamera(n_rows=20, n_cols=10)  # 45,000 pixels x 1,024 rays = 46 M rays
    raw = simulate.render(cam, uniform_scene(cam, 0.75), rays_per_pixel=1024)
    assert np.all(raw == 0.75)


# ---- optics -------------------------------------------------------------------------

def test_paper_camera_is_paraxial_and_a_fast_lens_warns():
    assert PAPER_CAMERA.paraxial_error < 0.02 and PAPER_CAMERA.max_ray_angle_rad < 0.2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        PlenopticCamera()  # the paper's camera: no warning
    with pytest.warns(UserWarning, match="paraxial"):
        cam = PlenopticCamera(aperture_mm=300.0)
    assert cam.paraxial_error > PARAXIAL_LIMIT


def test_object_exactly_at_the_focal_length_rejected():
    with pytest.raises(ValueError, match="infinity or virtual"):
        PAPER_CAMERA.image_distance_mm(150.0)  # 1/(1/F - 1/z) would divide by zero


# ---- refocusing ---------------------------------------------------------------------

def _views(seed=0, n=5, r=12, c=9):
    return np.random.default_rng(seed).random((n, n, r, c), dtype=np.float32)


@pytest.mark.parametrize("interpolation", ["bilinear", "nearest"])
def test_shift_beyond_the_image_gives_zero_not_nan(interpolation):
    v = _views()
    st_ = focal_stack(v, [40.0, -40.0, 0.0], interpolation=interpolation)
    assert np.all(np.isfinite(st_))
    # only the centre view reaches any pixel at +-40 lenslets per view: it alone is the image
    assert np.allclose(st_[0], v[2, 2]) and np.allclose(st_[1], v[2, 2])


def test_shift_beyond_the_image_with_the_centre_view_masked_is_zero():
    mask = aperture_mask(5)
    mask[2, 2] = False
    st_ = focal_stack(_views(), [40.0], mask)
    assert np.all(st_ == 0.0)  # no view reaches any pixel: defined as 0, never 0/0


def test_negative_zero_slope_equals_zero_slope():
    v = _views()
    assert np.array_equal(focal_stack(v, [-0.0]), focal_stack(v, [0.0]))


@pytest.mark.parametrize("level", [0.0, 1.0])
def test_all_zero_and_saturated_light_fields(level):
    v = np.full((5, 5, 12, 9), level, np.float32)
    for interp in ("bilinear", "nearest"):
        assert np.all(focal_stack(v, [-1.3, 0.0, 2.7], interpolation=interp) == level)
    f = FourierSlice(v, 3.0).stack([-1.3, 0.0, 2.7])
    # Fourier slice: exact for black, within its Kaiser-Bessel resampling error (0.1 %) saturated
    assert np.all(np.isfinite(f)) and np.abs(f - level).max() <= 2e-3 * level


def test_slope_search_on_a_black_light_field():
    # every sharpness score is 0 (the normalised variance of an image with mean 0 is 0
    # by definition): no focus to find, said so (it had returned a slope for a flat curve)
    for metric in ("tenengrad", "normvar", "laplacian"):
        with pytest.raises(ValueError, match="no focus to find"):
            find_sharpest_slope(np.zeros((5, 5, 20, 20), np.float32), (4, 16, 4, 16), lo=-1, hi=1, metric=metric)
    for lo, hi in ((1, -1), (0.2, 0.2)):        # the ends swapped or equal: what the grid needs, said
        with pytest.raises(ValueError, match="finite ends lo < hi"):
            find_sharpest_slope(np.zeros((5, 5, 20, 20), np.float32), (4, 16, 4, 16), lo=lo, hi=hi)
    zero = np.zeros((8, 8))
    assert normalized_variance(zero) == tenengrad(zero) == variance_of_laplacian(zero) == 0.0


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_or_inf_anywhere_rejected(bad):
    v = _views()
    v[4, 0, 11, 8] = bad
    with pytest.raises(ValueError, match="NaN or inf"):
        focal_stack(v, [0.5])
    with pytest.raises(ValueError, match="NaN or inf"):
        FourierSlice(v, 1.0)
    raw = np.zeros((30, 45), np.float32)
    raw[29, 44] = bad
    with pytest.raises(ValueError, match="NaN or inf"):
        raw_to_views(raw, 15)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), slopes=st.lists(st.floats(-6, 6, allow_nan=False), min_size=1, max_size=4),
       n=st.sampled_from([1, 3, 5]), interpolation=st.sampled_from(["bilinear", "nearest"]))
def test_refocused_pixels_are_convex_combinations_of_the_views(seed, slopes, n, interpolation):
    # shift-and-sum normalised by the contributing views is a weighted mean: every output
    # pixel lies within the range of the light field, whatever the slope
    v = np.random.default_rng(seed).random((n, n, 7, 6), dtype=np.float32) * 3 - 1
    out = focal_stack(v, slopes, interpolation=interpolation)
    assert out.shape == (len(slopes), 7, 6) and np.all(np.isfinite(out))
    assert out.min() >= v.min() - 1e-6 and out.max() <= v.max() + 1e-6


@settings(max_examples=60, deadline=None)
@given(depth=st.floats(-60.0, 60.0, allow_nan=False))
def test_slope_depth_round_trip_property(depth):
    s = PAPER_CAMERA.slope_for_depth(depth)
    assert np.isfinite(s) and abs(PAPER_CAMERA.depth_for_slope(s) - depth) < 1e-9 * max(1.0, abs(depth))


# ---- training -----------------------------------------------------------------------

@pytest.mark.parametrize("level", [0.0, 1.0])
def test_black_and_saturated_targets_keep_the_loss_finite(level):
    import keras
    from lf_flame.config import ModelConfig
    from lf_flame.learn.model import build_decoder
    keras.utils.set_random_seed(0)
    dec = build_decoder((2, 1, 2048), 6, 4, ModelConfig())
    dec.compile(optimizer=keras.optimizers.Adam(1e-3), loss="mse")
    x = np.random.default_rng(0).standard_normal((4, 2, 1, 2048)).astype(np.float32) * 50
    before = np.abs(np.asarray(dec.predict_on_batch(x)) - level).mean()
    h = dec.fit(x, np.full((4, 6, 4, 4), level, np.float32), batch_size=2, epochs=10, verbose=0).history["loss"]
    after = np.asarray(dec.predict_on_batch(x))
    # the sigmoid output approaches 0 or 1 without reaching it: finite loss, no NaN
    assert np.all(np.isfinite(h)) and np.all(np.isfinite(after))
    assert np.abs(after - level).mean() < before


def test_resumed_epoch_sees_the_same_batches():
    from lf_flame.learn.features import FeatureBatches
    fresh = FeatureBatches("unused.h5", None, np.arange(20), 2, True, seed=7)
    orders = [fresh._order.copy()]
    for _ in range(3):
        fresh.on_epoch_end()
        orders.append(fresh._order.copy())
    resumed = FeatureBatches("unused.h5", None, np.arange(20), 2, True, seed=7, start_epoch=3)
    assert np.array_equal(resumed._order, orders[3]) and not np.array_equal(orders[2], orders[3])


# ---- determinism and writing --------------------------------------------------------

CAM = PlenopticCamera(n_rows=20, n_cols=10)
CFG = DatasetConfig(n_samples={"shapes": 3, "flame": 3}, rays_per_pixel=1, seed=5)
SLOPES = [CAM.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)]

_GENERATE = """
import sys
from lf_flame.learn import dataset as D
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.config import DatasetConfig
cam = PlenopticCamera(n_rows=20, n_cols=10)
cfg = DatasetConfig(n_samples={"shapes": 3, "flame": 3}, rays_per_pixel=1, seed=5)
D.generate(sys.argv[1], cam, cfg, "shapes", [cam.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)],
           progress=False)
"""


def test_dataset_bit_identical_across_runs_and_thread_counts(tmp_path):
    a = D.generate(tmp_path / "a.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    b = tmp_path / "b.h5"
    subprocess.run([sys.executable, "-c", _GENERATE, str(b)], check=True,
                   env=dict(os.environ, NUMBA_NUM_THREADS="1"))
    with h5py.File(a) as fa, h5py.File(b) as fb:
        for k in ("raw", "gt", "params", "split/train", "split/val", "split/test"):
            assert np.array_equal(fa[k][:], fb[k][:]), k


def test_disk_full_while_writing_loses_nothing(tmp_path, monkeypatch):
    p = D.generate(tmp_path / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    before = p.read_bytes()
    real, calls = h5py.Dataset.__setitem__, {"n": 0}

    def full_disk(self, key, value):
        if self.name == "/gt":
            calls["n"] += 1
            if calls["n"] == 2:
                raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, key, value)

    monkeypatch.setattr(h5py.Dataset, "__setitem__", full_disk)
    other = [s + 0.01 for s in SLOPES]  # a rebuild with other settings fails half-way
    with pytest.raises(OSError, match="No space left"):
        D.generate(p, CAM, CFG, "shapes", other, progress=False)
    assert p.read_bytes() == before  # the finished file is untouched
    partial = p.with_name(p.name + ".partial")
    with h5py.File(partial) as f:
        assert f["done"][:].tolist() == [1, 0, 0]  # the failed sample is not marked done
    monkeypatch.setattr(h5py.Dataset, "__setitem__", real)
    D.generate(p, CAM, CFG, "shapes", other, progress=False)  # disk freed: the run resumes
    clean = D.generate(tmp_path / "clean.h5", CAM, CFG, "shapes", other, progress=False)
    with h5py.File(p) as f, h5py.File(clean) as g:
        assert np.array_equal(f["raw"][:], g["raw"][:]) and np.array_equal(f["gt"][:], g["gt"][:])


def test_disk_full_keeps_the_old_text_file(tmp_path, monkeypatch):
    target = tmp_path / "table.md"
    atomic_write_text(target, "old table")
    real = type(target).write_text

    def full_disk(self, *a, **k):
        real(self, "half a ta")  # a partial write, then the disk is full
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(type(target), "write_text", full_disk)
    with pytest.raises(OSError):
        atomic_write_text(target, "new table")
    assert target.read_text() == "old table"



def test_every_documented_hard_case_has_its_test():
    import ast
    import re
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs/hard_cases.md").read_text()
    cases = re.findall(r"^\| (\d+) \|", doc, flags=re.M)
    assert len(cases) >= 30 and cases == [str(i) for i in range(1, len(cases) + 1)]
    for file, name in re.findall(r"`(test_\w+\.py)::(test_\w+)`", doc):
        tree = ast.parse((root / "tests" / file).read_text())
        assert name in {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}, f"{file}::{name}"
