"""Refocusing: sub-aperture views, shift-and-sum focal stacks and the slope search.

:mod:`.shift_and_sum` splits a raw image into views and refocuses them at a slope (lenslets
per view; Ng et al. 2005, the paper's Eq. 2) by bilinear shift-and-sum or the Fourier
slice; :mod:`.slope_search` finds the sharpest slope of a region; Numba kernels in :mod:`._kernels`.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["shift_and_sum", "slope_search"],
    submod_attrs={
        "shift_and_sum": ["raw_to_views", "views_to_raw", "aperture_mask", "INTERPOLATIONS", "METHODS",
                 "focal_stack", "FourierSlice", "refocus", "refocus_views"],
        "slope_search": ["variance_of_laplacian", "tenengrad", "normalized_variance", "SHARPNESS",
                 "SlopeSearch", "find_sharpest_slope"],
    },
)
