import os

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")


def _own_cache():
    """The suite's own lf_flame cache (library data read once; lf_flame.optics.colour.cache_dir), removed at exit."""
    import atexit
    import shutil
    import tempfile
    path = tempfile.mkdtemp(prefix="lf_flame_test_cache_")
    atexit.register(shutil.rmtree, path, True)
    return path


os.environ["LF_FLAME_CACHE"] = _own_cache()

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from lf_flame.simulate import scenes  # noqa: E402
from lf_flame.optics.camera import PlenopticCamera  # noqa: E402


@pytest.fixture(scope="session")
def small_camera():
    """The paper's optics with a 41 x 41 lenslet grid: same slopes, fast to render."""
    return PlenopticCamera(n_rows=41, n_cols=41)


def _uniform_scene(cam, level=0.5):
    """One additive plane of constant radiance ``level`` filling 10x the field of view at
    depth 0, no aperture, cos^4 or occlusion: every pixel sees exactly ``level``."""
    h, w = cam.field_of_view_mm(0.0)
    layer = scenes.Layer(np.full((4, 4), level, np.float32), None, 0.0, (0.0, 0.0), (10 * h, 10 * w))
    return scenes.Scene("uniform", (layer,), scenes.Effects(aperture=False, cos4=False, occlusion=False))


@pytest.fixture(scope="session")
def uniform_scene():
    """Factory ``uniform_scene(camera, level)`` of a uniform-plane scene."""
    return _uniform_scene


@pytest.fixture
def colour_capture(tmp_path, capsys):
    """Factory ``colour_capture(seed, rays, white_rays=8)``: the example camera with an RGGB CFA from the command line
    (its file ``colour.toml`` in ``tmp_path``), its white image -> ``calibrate`` (``cal.json``), and a colour-depth
    scene of that seed (``scene.npz``) decoded with its channels apart (``scene.h5``); returns the camera file."""
    from pathlib import Path

    from lf_flame.cli import main
    sheet = (Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
    cam = tmp_path / "colour.toml"
    cam.write_text(sheet + 'cfa = "RGGB"\n')
    d = str(tmp_path)

    def run(*argv):
        assert main([str(x) for x in argv]) == 0, capsys.readouterr().err

    def make(seed, rays, white_rays=8):
        run("simulate", "--camera", cam, "--scene", "white", "--rays-per-pixel", white_rays, "--out", f"{d}/white.npz")
        run("calibrate", f"{d}/white.npz", "--out", f"{d}/cal.json")
        run("simulate", "--camera", cam, "--scene", "colour-depth", "--seed", seed, "--rays-per-pixel", rays,
            "--out", f"{d}/scene.npz")
        run("decode", f"{d}/scene.npz", "--calibration", f"{d}/cal.json", "--camera", cam, "--out", f"{d}/scene.h5")
        return cam
    return make
