"""Real cameras: white-image grid calibration and decoding of captures into views.

:mod:`.calibration` finds the lenslet grid (pitch, rotation, offset, layout) from a white
image (Dansereau et al., CVPR 2013); :mod:`.decoding` resamples a capture onto that
grid and writes its sub-aperture views.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["calibration", "decoding"],
    submod_attrs={
        "calibration": ["CALIBRATION_FORMAT", "CALIBRATION_VERSION", "CalibrationError", "GridCalibration",
                 "load_image", "file_digest", "lattice_from_autocorrelation", "spot_centres",
                 "calibrate"],
        "decoding": ["check_grid", "view_positions", "hex_to_square", "decode", "save_views", "load_views"],
    },
)
