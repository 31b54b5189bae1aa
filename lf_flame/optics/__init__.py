"""The camera's optics: ray transfer (ABCD) matrices and the plenoptic 1.0 camera.

:mod:`.matrices` holds the 4x4 ray transfer matrices (free space, thin lens, aperture stop,
microlens array; Gerrard & Burch, *Introduction to Matrix Methods in Optics*);
:mod:`.camera` the paper's camera (main lens, microlens array, sensor; SPEC.md) and a
user's own, with its lenslet grid and the slope of every depth; :mod:`.depth_range` the depths it can refocus
and the planes it refuses; :mod:`.camera_file` a user's
camera from its datasheets (a TOML camera file) and the perfect-grid camera of its decoded views;
:mod:`.colour` a colour sensor (Bayer CFA, channel sensitivities, Planck and soot band integrals).

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["camera", "camera_file", "colour", "depth_range", "matrices"],
    submod_attrs={
        "camera": ["GRID_LAYOUTS", "MAX_GRID_ROTATION_DEG", "PARAXIAL_LIMIT", "PlenopticCamera", "PAPER_CAMERA"],
        "depth_range": ["MAX_SEARCH_SLOPE", "NEAR_LIMIT", "imaging_range_mm", "search_range_mm", "check_imaging_range",
                        "check_planes_once"],
        "camera_file": ["DATASHEET_KEYS", "AGREEMENT", "camera_from_datasheet", "load_camera_file", "decoded_camera"],
        "colour": ["ALPHA_SOOT", "CHANNELS", "CFA_PATTERNS", "ColourSensor", "cfa_channels", "library_sensor",
                 "planck_radiance", "band_integrals", "mosaic"],
        "matrices": ["DET_TOL", "RayTransferMatrix", "free_space", "thin_lens", "ApertureStop",
                 "MicrolensArray"],
    },
)
