"""Real cameras: white-image grid calibration and decoding of captures into views.

:mod:`.images` reads and checks white, dark and raw images, :mod:`.clipping` finds where a sensor clipped
in them and :mod:`.black_level` what a capture reads where no light reaches it (a black level left in);
:mod:`.calibration` finds the lenslet grid (pitch, rotation, offset, layout) from a white
image (Dansereau et al., CVPR 2013), with the lattice's steps in :mod:`.lattice`; :mod:`.decoding` resamples a capture onto that
grid into its sub-aperture views, with the samples from clipped pixels, once :mod:`.grid_check` has found
the calibration's grid in it, and :mod:`.defects` a sensor's hot and dead pixels, repaired before it decodes;
:mod:`.views_file` writes and reads those views;
:mod:`.own_camera` gives the perfect-grid camera of those views (a camera file and the
calibration checked against each other) and the frame of its planes; :mod:`.readers`
reads any light field (a simulated raw image, decoded views, a raw capture decoded on the
fly) into one value (:mod:`.lightfield`), views with their camera, that every route takes.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["images", "clipping", "black_level", "lattice", "calibration", "grid_check", "view_grid", "decoding",
                "defects", "views_file", "own_camera", "lightfield", "readers"],
    submod_attrs={
        "images": ["load_image", "to_gray", "file_digest", "calibration_image"],
        "clipping": ["PILE_MIN_PIXELS", "PILE_RATIO", "LIT_SHARE", "CLIPPED_WARN", "clipping_pile", "auto_saturation",
                     "found_level", "clipped_share"],
        "black_level": ["UNLIT_SHARE", "MIN_UNLIT_PIXELS", "MIN_WHITE_CONTRAST", "BLACK_LEVEL_SHARE", "unlit_level"],
        "lattice": ["CalibrationError", "lattice_from_autocorrelation", "spot_centres"],
        "calibration": ["CALIBRATION_FORMAT", "CALIBRATION_VERSION", "GridCalibration", "calibrate"],
        "grid_check": ["check_grid"],
        "view_grid": ["view_positions", "interpolation_phases", "auto_bin", "hex_to_square", "views_shape",
                      "on_square_grid", "max_views", "views_for_pitch", "sample_offsets"],
        "decoding": ["decode", "decode_colour", "decode_capture_views", "decode_repaired", "clipped_samples",
                     "white_samples"],
        "defects": ["DEFECT_MARGIN", "DEFECT_SPREAD", "lenslet_offsets", "grid_offsets", "defective_pixels",
                    "repair_pixels", "capture_defects"],
        "views_file": ["save_views", "load_views", "load_clipped", "load_channels", "load_lattice"],
        "own_camera": ["PITCH_WARN", "PITCH_TOLERANCE", "DecodedFrame", "decoded_frame", "views_camera",
                       "nominal_views_camera", "decoded_views_camera"],
        "lightfield": ["LightField", "from_raw", "from_decoded"],
        "readers": ["RAW_SUFFIXES", "read_light_field", "decode_capture", "capture_sensor", "camera_differences",
                    "stored_camera_warning", "same_grid"],
    },
)
