"""The learned reconstructor: its noise model, its Wiener start, training, saving and the CLI route."""
import json
import subprocess
import sys

import h5py
import numpy as np
import pytest

from lf_flame.learn import reconstructor as L
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.fourier import wiener_start


@pytest.fixture(scope="module")
def cam():
    return PlenopticCamera(n_rows=40, n_cols=24)


def test_sensor_noise_gives_the_asked_snr_and_clips():
    rng = np.random.default_rng(0)
    clean = rng.uniform(0.0, 0.9, (5, 5, 30, 30))
    for snr in (10.0, 14.0, 20.0):
        noisy = L.sensor_noise(clean, snr, np.random.default_rng(1))
        measured = 10 * np.log10(np.sum(clean ** 2) / np.sum((noisy - clean) ** 2))
        assert abs(measured - snr) < 0.3, (snr, measured)
    bright = L.sensor_noise(clean * 2, None, rng)
    assert bright.max() == 1.0 and np.allclose(bright, np.minimum(clean * 2, 1.0))


def test_wiener_start_inverts_the_light_field_where_the_data_determine_it(cam):
    """Without noise and with a vanishing ridge, the per-frequency solve recovers one plane whose light stays
    on the sensor, and fits two planes' light field (their split at low frequencies, the light field's
    missing cone, is the ridge's choice); the refocused stack is blurred. A wrong spectrum, conjugate or
    frequency axis fails both."""
    r, c = np.mgrid[:40, :24]
    blobs = np.stack([np.exp(-((r - 18) ** 2 + (c - 10) ** 2) / 8.0), np.exp(-((r - 22) ** 2 / 30 + (c - 13) ** 2 / 6))])
    one = ExactOperator(cam, [8.0], precision="float64")
    wiener, refocused = wiener_start(one.matvec(blobs[0].ravel()).reshape(one.dimsd), one, lam=1e-7, rho=1e-7)
    err = np.linalg.norm(wiener[0] - blobs[0]) / np.linalg.norm(blobs[0])
    assert err < 0.01 and np.linalg.norm(refocused[0] - blobs[0]) / np.linalg.norm(blobs[0]) > 0.1, err
    two = ExactOperator(cam, [8.0, -6.0], precision="float64")
    views = two.matvec(blobs.ravel()).reshape(two.dimsd)
    wiener, refocused = wiener_start(views, two, lam=1e-7, rho=1e-7)
    fit = np.linalg.norm(two.matvec(wiener.ravel()) - views.ravel()) / np.linalg.norm(views)
    assert fit < 0.02 and np.linalg.norm(two.matvec(refocused.ravel()) - views.ravel()) / np.linalg.norm(views) > 0.2


@pytest.fixture(scope="module")
def tiny_model(cam, tmp_path_factory):
    cfg = L.ReconstructorConfig(epochs=3, base_channels=4, patience=3)
    train = L.training_samples(cam, 2, 11, cfg, progress=False)
    val = L.training_samples(cam, 1, 12, cfg, progress=False)
    model = L.train(cam, train, val, cfg, verbose=0)
    folder = model.save(tmp_path_factory.mktemp("reconstructor"))
    return model, folder, train


def test_training_samples_are_planes_with_their_truth(cam, tiny_model):
    x, y = tiny_model[2]
    assert x.shape[-1] == len(L.CHANNELS) and y.shape == x.shape[:3] + (1,)
    assert x.shape[1] % 8 == 0 and x.shape[2] % 8 == 0 and len(x) >= 4 * 2
    assert np.all(np.isfinite(x)) and y.min() >= 0 and y.max() > 0


def test_a_trained_reconstructor_saves_loads_and_refuses_another_camera(cam, tiny_model):
    model, folder, _ = tiny_model
    rng = np.random.default_rng(5)
    scene = L.training_scene(cam, rng, "depth")
    fine = ExactOperator(cam, L.scene_depths(scene), precision="float32", subsamples=2)
    op = fine.binned()
    views, fit = L.exact_light_field(scene, fine, rng, 14.0)
    planes = model.planes(views, op, fit)
    assert planes.shape == op.dims and planes.min() >= 0
    again = L.LearnedReconstructor.load(folder)
    assert np.allclose(again.planes(views, op, fit), planes, atol=1e-6 * max(planes.max(), 1e-12))
    assert model.record["epochs_run"] >= 1 and json.loads((folder / L.CONFIG_FILE).read_text())["camera"]
    rec = L.reconstruction(views, op, again, fit)
    assert rec.solver == "learned" and rec.planes.shape == op.dims and 0 < rec.residuals[-1] < 10
    other = ExactOperator(PlenopticCamera(n_rows=40, n_cols=26), L.scene_depths(scene), precision="float32")
    with pytest.raises(ValueError, match="another camera"):
        model.planes(np.zeros(other.dimsd), other)
    with pytest.raises(ValueError, match="lenslet grid"):
        L.reconstruction(views, fine, again, fit)
    with pytest.raises(FileNotFoundError, match="train-reconstructor"):
        L.LearnedReconstructor.load(folder / "absent")


def test_cli_reconstructs_with_a_trained_model(cam, tiny_model, tmp_path):
    _, folder, _ = tiny_model
    run = [sys.executable, "-m", "lf_flame"]
    raw = tmp_path / "flame.npz"
    cfg = tmp_path / "cam.toml"
    cfg.write_text(f"[camera]\nn_rows = {cam.n_rows}\nn_cols = {cam.n_cols}\n")
    subprocess.run(run + ["simulate", "--scene", "depth", "--camera", str(cfg), "--seed", "3", "--out", str(raw)],
                   check=True, capture_output=True)
    out = tmp_path / "learned.h5"
    p = subprocess.run(run + ["reconstruct", str(raw), "--depths", "scene", "--solver", "learned", "--model",
                              str(folder), "--out", str(out)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "learned" in p.stdout
    with h5py.File(out) as f:
        assert f.attrs["solver"] == "learned"
    bad = subprocess.run(run + ["reconstruct", str(raw), "--depths", "scene", "--solver", "learned", "--model",
                                str(tmp_path / "none"), "--out", str(tmp_path / "x.h5")], capture_output=True, text=True)
    assert bad.returncode != 0 and "train-reconstructor" in bad.stderr and not (tmp_path / "x.h5").exists()


def test_a_reconstructor_is_trained_for_a_real_grids_decoded_views(tmp_path):
    """make train-reconstructor CAMERA=cam.toml of a camera whose lenslet grid is not perfect (the example camera:
    10.57 px pitch, rotated, offset) had stopped on 'the exact operator needs a perfect lenslet grid'. Without its
    white-image calibration it is refused naming it; with it, the network is trained for the camera of the views that
    decoding with that calibration gives (what reconstruct --solver learned is then given)."""
    from pathlib import Path
    from lf_flame.cli import main
    from lf_flame.optics.camera_file import load_camera_file
    from lf_flame.real.calibration import GridCalibration
    from lf_flame.real.own_camera import decoded_views_camera
    from lf_flame.simulate import scenes, tracer
    root = Path(__file__).resolve().parents[1]
    example = str(root / "examples" / "own_camera.toml")
    cam = load_camera_file(example)
    np.save(tmp_path / "white.npy", tracer.render(cam, scenes.white_scene(cam), 16))
    assert main(["calibrate", str(tmp_path / "white.npy"), "--out", str(tmp_path / "cal.json")]) == 0
    run = [sys.executable, str(root / "experiments" / "learned.py"), "--camera", example, "--quick", "--stage", "train",
           "--out", str(tmp_path / "r"), "--models", str(tmp_path / "m"), "--cache", str(tmp_path / "c")]
    p = subprocess.run(run, capture_output=True, text=True)
    assert p.returncode == 2 and "give its white-image calibration" in p.stderr, p.stderr
    p = subprocess.run(run + ["--calibration", str(tmp_path / "cal.json")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    want = decoded_views_camera(cam, GridCalibration.load(tmp_path / "cal.json"))[0]
    assert L.LearnedReconstructor.load(tmp_path / "m").camera == want and want.perfect_grid
