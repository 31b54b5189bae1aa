import os

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")

import pytest  # noqa: E402

from lf_flame.camera import PlenopticCamera  # noqa: E402


@pytest.fixture(scope="session")
def small_camera():
    """The paper's optics with a 41 x 41 lenslet grid: same slopes, fast to render."""
    return PlenopticCamera(n_rows=41, n_cols=41)
