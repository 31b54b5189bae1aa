"""Temperature: two-colour pyrometry from one colour (Bayer) light field.

A colour plenoptic camera records one channel per pixel. :mod:`.mosaic` gives each view sample its
channel and levels the channels into one monochrome light field (for reconstruct and depth from
focus); :mod:`.channels` recovers two colour channels' emission on planes, each from its own
colour-filter-array samples (the exact operator's admm, the channels' resolution matched, or each
channel refocused); :mod:`.ratio` filters the
two channels' ratio per plane (Gaussian, guided, along the brightness contours);
:mod:`.axisymmetric` an axisymmetric flame's temperature T(r, y) and per voxel from each
channel's e(r, y) solved on its own samples; :mod:`.pyrometry` the blackbody calibration of
the channels' gain ratio (JSON, bound to its camera and CFA) and the band-integrated lookup
from two channels' ratio to temperature.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["axisymmetric", "channels", "mosaic", "pyrometry", "ratio"],
    submod_attrs={
        "axisymmetric": ["COLOUR_FILLS", "COLOUR_INNER", "AxisymmetricTemperature", "volume_temperature",
                         "axisymmetric_temperature"],
        "channels": ["CFA_ROUTES", "CFA_FILLS", "CFA_LAM", "CFA_TV", "MATCHED_SUBSAMPLES",
                     "MATCHED_SIGMA_NOISY", "MATCHED_KNOBS", "MATCHED_QUIET_NOISE", "MATCHED_RATIO_FILTER",
                     "DECODED_KNOBS", "DECODED_RATIO_FILTER",
                     "MATCHED_WIDE_NOISE", "admm_channel", "matched_channels", "matched_regime", "cfa_noise",
                     "route_operator", "refocus_channel", "channel_emission", "colour_truth"],
        "mosaic": ["channel_views", "channel_subviews", "cfa_blind", "channel_sum_views", "levelled_views",
                   "monochrome_light_field"],
        "pyrometry": ["T_RANGE_K", "MIN_FRACTION", "TemperatureCalibration", "model_ratio", "blackbody_ratio",
                      "fit_calibration", "lookup_table", "ratio_to_temperature", "bright_pixels",
                      "temperature_planes", "wien_temperature", "write_calibration", "load_calibration"],
        "ratio": ["SMOOTH_SIGMA", "smooth_planes", "guided_filter", "guided_ratio", "contour_ratio",
                  "filter_ratio"],
    },
)
