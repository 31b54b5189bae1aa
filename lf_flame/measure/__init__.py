"""Measurement: flame diagnostics per plane and image scores.

:mod:`.diagnostics` measures a flame on one plane (height, base, widths, radial
profiles, in mm) with flags for heights it cannot trust; :mod:`.scoring` scores focal
stacks' diagnostics against a scene's truth; :mod:`.metrics` SSIM and PSNR per plane
(scikit-image); :mod:`.pyrometry` two-colour temperature from two channels' emission;
:mod:`.figures` draws planes in object-space mm with their colour bars (the commands' figures).

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["diagnostics", "figures", "metrics", "pyrometry", "scoring"],
    submod_attrs={
        "diagnostics": ["SEGMENT_FRACTION", "EDGE_FIT_RANGE", "TAIL_FALL", "PEDESTAL_GAP", "TIP_PEDESTAL_MM",
                 "FLAGS", "MIN_AREA_LENSLETS", "RADIAL_FRACTIONS", "EMISSION_MEASURE",
                 "EmptyPlaneError", "lenslet_size_mm",
                 "lenslet_to_object_mm", "RadialProfile", "FlameMeasurement", "measure_flame",
                 "flame_truth", "plot_profiles", "profiles_figure"],
        "figures": ["signed", "plane_extent_mm", "show_plane", "add_colorbar", "planes_figure", "save_figure"],
        "metrics": ["ssim_per_plane", "psnr_per_plane", "mean_ssim"],
        "pyrometry": ["T_RANGE_K", "MIN_FRACTION", "TemperatureCalibration", "model_ratio", "blackbody_ratio",
                 "fit_calibration", "lookup_table", "ratio_to_temperature", "bright_pixels", "temperature_planes",
                 "wien_temperature", "write_calibration", "load_calibration"],
        "scoring": ["measure_stack", "score_stacks", "error_table"],
    },
)
