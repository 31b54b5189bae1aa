"""Tomography: each plane's emission, not its blurred focal stack.

Flames are optically thin, so a light field is a linear function of the emission on
the planes. :mod:`.operator` is that camera map as a linear operator (the simulator's
tracer with fixed rays, recorded once, kernels in :mod:`._kernels`); :mod:`.exact` the
same map without Monte-Carlo noise (per-view convolutions applied by FFT, with kernels by deterministic
quadrature in :mod:`.quadrature`, its loops in :mod:`._exact_kernels`); :mod:`.lattice` that map for decoded
views (decoding's interpolation, a hexagonal lenslet lattice solved on itself); :mod:`.resolution` the
camera's depth-resolution map from that map's per-frequency normal matrices; :mod:`.solvers`
recovers the emission (the PyLops/PyProximal solvers in :mod:`.proximal`), and :mod:`.fourier` on the exact
operator's per-frequency normal matrices (ADMM; kernels in :mod:`._fourier_kernels`);
:mod:`.depth` finds the depths that hold emission (depth from focus per region),
:mod:`.found_planes` solves on them, :mod:`.peel` searches that solve's residual for depths the votes missed and
:mod:`.refine` moves the depths of flames one behind another to the residual's least (and searches it once more);
:mod:`.axisymmetric` an axisymmetric flame's emission e(r, y) revolved onto a dense stack (its axis searched on the
data residual; the model and its fit in :mod:`.revolve`, the axis's lateral position and the field's edge from the
views in :mod:`.axis`); :mod:`.truth` puts a simulated scene's truth on the same grids; :mod:`.scoring` scores
planes against it;
:mod:`.volume` solves a dense stack with a prior (none, TV, sparse, axisymmetric) and
states the depth resolution it carries; :mod:`.decoded` turns decoded views of a user's camera into the exact operator's data and
puts a simulated scene's truth in their frame;
:mod:`.files` saves, loads and draws a reconstruction.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["axis", "axisymmetric", "decoded", "defaults", "depth", "exact", "files", "focus", "found_planes",
                "fourier", "fourier_system", "lattice", "noise_knobs", "operator", "peel", "proximal", "quadrature",
                "refine", "conditioning", "resolution", "revolve", "scoring", "solvers", "truth", "volume"],
    submod_attrs={
        "axisymmetric": ["AXI_LAM", "AXI_FILLS", "AXI_INNER", "AxisymmetricVolume", "solve_axisymmetric"],
        "revolve": ["RevolveOperator", "NormalMatrices", "fit_emission", "wide_operator"],
        "axis": ["EDGE_SHARE", "MIRROR_ONE_SIDED", "reaches_edge", "lit_profile", "axis_x_from_views"],
        "decoded": ["MIN_WHITE", "white_views", "decoded_problem", "decoded_truth", "decoded_plane_truth", "fit_data"],
        "depth": ["SLOPE_STEP", "MERGE_MM", "MERGE_PARALLAX", "MIN_SEPARATION_MM", "FoundDepths", "find_depths",
                  "merge_depths", "plane_runs", "depth_scale", "depth_tolerance_scale", "depth_tolerances"],
        "peel": ["RESIDUAL_PROMINENCE", "RESIDUAL_SHARE", "PEEL_ROUNDS", "missed_depths", "peel_planes"],
        "refine": ["REFINE_STEPS", "REFINE_SECANT_MAX", "REFINE_MAX_SLOPE", "REFINE_TOL", "REFINE_REACH",
                   "REFINED_PROMINENCE", "REFINED_SHARE", "REFINED_QUIET_PROMINENCE", "slope_jacobian", "secant_scale",
                   "refine_planes", "refined_regions", "peel_and_refine"],
        "found_planes": ["SUPPORT_DILATION", "NEAR_PARALLAX", "SUPPORT_KNOBS", "FOUND_PLANES_KNOBS", "plane_support",
                         "near_plane_support", "near_pairs", "on_given_planes", "found_support", "found_planes_knobs",
                         "find_planes"],
        "quadrature": ["QUADRATURE_NODES", "SHIFT_TOLERANCE", "ExactKernels", "exact_kernels", "chain_coefficients",
                       "sub_view_chain"],
        "exact": ["PRECISIONS", "OFFSET_BINS", "OFFSET_TOLERANCE", "offset_bins_for", "ExactOperator",
                  "emission_operator"],
        "lattice": ["KERNEL_POINTS", "LAYOUTS", "nearest_site", "hexagon_points", "rd_points", "lattice_kernels",
                    "to_axial", "LatticeOperator", "LatticeSolve", "solve_on_lattice"],
        "fourier": ["solve_admm", "fill_data", "wiener_start", "backprojection_weight", "coarse_operator"],
        "fourier_system": ["FourierSystem", "fourier_system", "admm_system", "normal_matrices"],
        "noise_knobs": ["relative_noise", "noise_norm", "noise_regime", "admm_knobs", "admm_subsamples"],
        "files": ["save_reconstruction", "load_reconstruction", "load_found", "plot_reconstruction", "reconstruction_figure"],
        "operator": ["ADJOINT_BLOCKS", "RAY_TABLE_MAX_BYTES", "plane_grid", "PlanesOperator", "EmissionOperator",
                     "normalised_adjoint", "check_views"],
        "proximal": ["PD_RESIDUAL_EVERY", "solve_lsqr", "solve_fista", "solve_pd_tv"],
        "conditioning": ["kernel_response", "normal_matrix", "pair_conditions"],
        "resolution": ["FEATURE_SIZES_MM", "CONDITIONS", "AXES", "MAX_PLANES", "DepthResolution", "stack_depths",
                       "resolution_from_kernels", "depth_resolution", "plot_depth_resolution"],
        "scoring": ["score_planes", "score_flames"],
        "solvers": ["SOLVERS", "DEFAULT_ITERS", "DEFAULT_TV", "DEFAULT_SOLVER", "EXACT_SOLVER",
                 "Reconstruction", "lipschitz_bound", "reconstruct", "EDGE_BAND_LENSLETS", "EDGE_SHARE_WARN",
                 "edge_shares", "EDGE_BODY", "MISFIT_WARN", "MISFIT_NOISE", "fitted_residual",
                 "data_misfit", "misfit_is_high"],
        "truth": ["resample_layer", "scene_truth", "depth_shares", "truth_depths", "bin_planes"],
        "volume": ["volume_depths", "solve_volume"],
    },
)
