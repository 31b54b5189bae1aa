import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.optics.matrices import ApertureStop, MicrolensArray, RayTransferMatrix, free_space, thin_lens


def test_composition_order_matches_matrix_product():
    a, b = thin_lens(50.0), free_space(20.0)
    assert np.allclose((a @ b).matrix, a.matrix @ b.matrix)
    y, t = (a @ b).apply(1.0, 0.1)
    y2, t2 = a.apply(*b.apply(1.0, 0.1))
    assert np.isclose(y, y2) and np.isclose(t, t2)


def test_imaging_condition_gives_b_zero_and_magnification():
    # object at the focal plane is imaged onto the MLA: B = 0, A = -d/z
    m = PAPER_CAMERA.object_to_mla(PAPER_CAMERA.focus_distance_mm)
    assert abs(m.B) < 1e-9
    assert np.isclose(m.A, -PAPER_CAMERA.mla_distance_mm / PAPER_CAMERA.focus_distance_mm)


def test_inverse_undoes_element():
    m = free_space(12.0) @ thin_lens(-30.0) @ free_space(3.0)
    assert np.allclose((m @ m.inverse()).matrix, np.eye(2), atol=1e-12)


@pytest.mark.parametrize("bad", [0.0, float("nan"), float("inf")])
def test_thin_lens_rejects_bad_focal_length(bad):
    with pytest.raises(ValueError, match="focal_length_mm"):
        thin_lens(bad)


def test_non_unit_determinant_rejected():
    with pytest.raises(ValueError, match="determinant"):
        RayTransferMatrix(2.0, 0.0, 0.0, 1.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.floats(0.5, 500.0), st.booleans()), min_size=1, max_size=40))
def test_long_random_chains_keep_unit_determinant(elements):
    m = free_space(0.0)
    for is_lens, v, neg in elements:
        e = thin_lens(-v if neg else v) if is_lens else free_space(v)
        m = e @ m
    assert abs(m.det - 1.0) < 1e-12 * max(1.0, abs(m.A * m.D))


@pytest.mark.parametrize("field,value", [("pitch_mm", 0.0), ("focal_length_mm", -0.4), ("n_rows", 0)])
def test_microlens_array_validates(field, value):
    kw = dict(pitch_mm=0.112, focal_length_mm=0.4, n_rows=4, n_cols=4)
    kw[field] = value
    with pytest.raises(ValueError, match=field):
        MicrolensArray(**kw)


def test_microlens_border_rule_and_centres():
    mla = MicrolensArray(0.1, 0.4, 4, 4)
    # the border y = 0 between rows 1 and 2 belongs to row 2 (floor rule), x = 0 to column 2
    r, c = mla.lenslet_index(np.array([0.0, 0.05, -0.05]), np.array([0.0, 0.05, -0.05]))
    assert list(r) == [2, 2, 1] and list(c) == [2, 1, 2]
    yc, xc = mla.centre(r, c)
    assert np.allclose(yc, [0.05, 0.05, -0.05]) and np.allclose(xc, [-0.05, 0.05, -0.05])
    # a ray through a lenslet centre is not deviated; one at its edge turns by -(y - yc)/f
    ty, tx = mla.apply(np.array([0.05, 0.09]), np.array([0.0, 0.0]), np.array([-0.05, -0.05]), np.zeros(2))
    assert np.allclose(ty, [0.0, -0.04 / 0.4]) and np.allclose(tx, 0.0)


def test_paper_camera_geometry():
    cam = PAPER_CAMERA
    assert np.isclose(cam.mla_distance_mm, 277.8409, atol=1e-3)
    assert np.isclose(cam.aperture_diameter_mm, 77.795, atol=1e-3)
    assert cam.sensor_shape == (2700, 1350)
    slopes = [cam.slope_for_depth(d) for d in (-10, 0, 10, 20)]
    assert np.allclose(slopes, [-1.249, 0.0, 1.175, 2.281], atol=2e-3)


@pytest.mark.parametrize("dz", [-30.0, -10.0, 0.0, 7.5, 20.0, 60.0])
def test_slope_depth_round_trip(dz):
    cam = PAPER_CAMERA
    assert np.isclose(cam.depth_for_slope(cam.slope_for_depth(dz)), dz, atol=1e-9)


@pytest.mark.parametrize("kw,match", [
    (dict(main_focal_mm=-150.0), "main_focal_mm"),
    (dict(mla_pitch_mm=0.0), "mla_pitch_mm"),
    (dict(focus_distance_mm=150.0), "focal length"),
    (dict(pixels_per_lenslet=0), "pixels_per_lenslet"),
    (dict(pixels_per_lenslet=True), "pixels_per_lenslet"),
    (dict(n_rows=np.float64(90.0)), "n_rows must be a positive integer"),
])
def test_impossible_cameras_rejected(kw, match):
    with pytest.raises(ValueError, match=match):
        PlenopticCamera(**kw)


def test_depths_and_pitches_that_mean_nothing_are_refused_by_name():
    """A NaN depth, a plane behind the main lens, a pitch under a pixel and a zero slope step each raise a
    ValueError naming them (they had given 'inside the focal length' for NaN, negative field sizes, 0 or -3 views,
    a ZeroDivisionError)."""
    from lf_flame.optics.camera import views_for_pitch
    from lf_flame.tomo.depth import depth_per_slope
    with pytest.raises(ValueError, match="finite number of mm"):
        PAPER_CAMERA.slope_for_depth(np.nan)
    with pytest.raises(ValueError, match="behind the main lens"):
        PAPER_CAMERA.field_of_view_mm(-400.0)
    for bad in (0, -3, np.nan, True):
        with pytest.raises(ValueError, match="pitch must be a finite number of pixels >= 1"):
            views_for_pitch(bad)
    assert views_for_pitch(np.float32(10.57)) == 10
    with pytest.raises(ValueError, match="step must be a finite slope > 0"):
        depth_per_slope(PAPER_CAMERA, 0.0)


def test_a_camera_from_numpy_numbers_is_the_same_camera():
    """An HDF5 file's attributes read back as NumPy scalars: ``from_dict`` of them gives the camera they came from,
    its numbers Python's (its JSON the same)."""
    d = {k: np.asarray(v)[()] for k, v in PAPER_CAMERA.to_dict().items() if v is not None}
    assert all(type(v).__module__ == "numpy" for k, v in d.items() if k != "grid_layout")
    cam = PlenopticCamera.from_dict(d)
    assert cam == PAPER_CAMERA and cam.to_json() == PAPER_CAMERA.to_json()
    assert type(cam.n_rows) is int and type(cam.main_focal_mm) is float


def test_sensor_off_focus_warns():
    with pytest.warns(UserWarning, match="plenoptic 1.0"):
        PlenopticCamera(mla_sensor_mm=0.5)


def test_object_inside_focal_length_has_no_real_image():
    with pytest.raises(ValueError, match="infinity or virtual"):
        PAPER_CAMERA.image_distance_mm(100.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_aperture_stop_rejects_bad_diameter(bad):
    with pytest.raises(ValueError, match="diameter"):
        ApertureStop(bad)


def test_aperture_stop_passes_its_rim_and_no_further():
    stop = ApertureStop(2.0)
    assert stop.passes(1.0, 0.0) and stop.passes(0.0, -1.0)
    assert not stop.passes(1.0 + 1e-12, 0.0)
    assert stop.matrix.det == 1.0
