"""Measurement: flame diagnostics per plane and image scores.

:mod:`.diagnostics` measures a flame on one plane (height, base, widths, radial
profiles, in mm) with flags for heights it cannot trust; :mod:`.scoring` scores focal
stacks' diagnostics against a scene's truth; :mod:`.metrics` SSIM and PSNR per plane
(scikit-image); :mod:`.figures` draws planes in object-space mm with their colour bars (the commands' figures,
the profiles figure among them).

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["diagnostics", "figures", "metrics", "scoring"],
    submod_attrs={
        "diagnostics": ["SEGMENT_FRACTION", "EDGE_FIT_RANGE", "TAIL_FALL", "PEDESTAL_GAP", "TIP_PEDESTAL_MM",
                 "FLAGS", "MIN_AREA_LENSLETS", "RADIAL_FRACTIONS", "EMISSION_MEASURE", "PICKS",
                 "EmptyPlaneError", "lenslet_size_mm",
                 "lenslet_to_object_mm", "RadialProfile", "FlameMeasurement", "measure_flame",
                 "SEPARATE_SHARE", "separate_flame_bands", "flame_truth"],
        "figures": ["signed", "plane_extent_mm", "show_plane", "add_colorbar", "planes_figure", "save_figure",
                    "plot_profiles", "profiles_figure"],
        "metrics": ["ssim_per_plane", "psnr_per_plane", "mean_ssim", "own_error"],
        "scoring": ["measure_stack", "score_stacks", "error_table"],
    },
)
