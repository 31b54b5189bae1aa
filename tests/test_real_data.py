"""A real light field: napari-lf's GUVExperim1 capture (436 x 436, 16 bit), calibrated and decoded.

The Makefile's set-up installs the data (``$(NLF)/.installed``, a dependency of ``make
test``) into ``.bench/napari-lf``; lf_flame never imports napari_lf. Without the folder
(no network at set-up) the test is skipped, saying so.
"""
from pathlib import Path

import numpy as np
import pytest

from lf_flame.real import calibration as calibrate
from lf_flame.real import decoding as decode
from lf_flame.real.images import load_image
from lf_flame.refocus.shift_and_sum import aperture_mask
from lf_flame.refocus.slope_search import find_sharpest_slope

EXAMPLES = Path(__file__).resolve().parents[1] / ".bench" / "napari-lf" / "napari_lf" / "examples"
GUV = EXAMPLES / "GUVExperim1"

pytestmark = pytest.mark.skipif(not GUV.is_dir(), reason=f"napari-lf example data not installed at {EXAMPLES} "
                                "(make .bench/napari-lf/.installed)")


def _periodogram_pitch(img):
    from scipy import signal
    out = []
    for axis in (0, 1):
        f, p = signal.periodogram(img.mean(axis=axis), window="hann", nfft=1 << 20, detrend="linear")
        band = (f > 1 / 100) & (f < 1 / 5)
        out.append(1 / f[band][np.argmax(p[band])])
    return float(np.mean(out))


def test_real_capture_calibrates_decodes_and_refocuses():
    white = load_image(GUV / "Radiometry_GUVExperim1.tif")
    dark = load_image(GUV / "DarkFrame_GUVExperim1.tif")
    raw = load_image(GUV / "Lightfield_GUVExperim1.tif")
    cal = calibrate.calibrate(white, dark)
    # independent pitch: the periodogram of the mean row and column profiles (15.40 px);
    # the stated optics (100 um lenslets / 6.5 um pixels, 1:1 relay) give 15.385 px
    assert abs(cal.pitch_px / _periodogram_pitch(white - dark) - 1) < 0.002, cal.pitch_px
    assert abs(cal.pitch_px / (100 / 6.5) - 1) < 0.01
    assert cal.residual_rms_px < 0.3 and cal.layout == "square"
    views = decode.decode(raw, cal, white, dark)
    assert views.shape == (15, 15, cal.n_rows, cal.n_cols) and np.all(np.isfinite(views))
    decode.check_grid(raw - dark, cal)
    # the vesicle's rim is sharpest at one slope, inside the range, well above the ends
    s = find_sharpest_slope(views, (12, 20, 14, 22), lo=-2, hi=2, mask=aperture_mask(15, "circular"))
    assert -1.5 < s.slope < 1.5 and s.scores.max() > 10 * max(s.scores[0], s.scores[-1])
    # another capture's white image is not this calibration's grid
    other = load_image(EXAMPLES / "antleg" / "radiometry_frame.png")[:436, :436]
    with pytest.raises(ValueError, match="another camera"):
        decode.decode(other, cal)
