"""Simulation: scenes and the ray tracer that renders their raw light-field images.

:mod:`.layers` is what a scene is made of (layers, effects); :mod:`.scenes` builds layered scenes (the paper's
shapes and flames at four depths, overlaps, points); :mod:`.scenes_depth` flames at random depths and one behind
another; :mod:`.scenes_volume` axisymmetric volumetric flames (the sheath on the optical
axis; sheath, filled core about any vertical axis) and non-axisymmetric ones (leaning, with a lobe); :mod:`.scenes_time` flickering flames over time; :mod:`.scenes_temperature` flames with a
temperature field seen in colour (still or flickering), rendered by :mod:`.colour` (a Bayer mosaic of per-channel renders); :mod:`.scenes_volume_temperature` an
axisymmetric volumetric flame with a temperature field T(r, y) in colour; :mod:`.tracer` renders
them by tracing rays backward through the camera's ray transfer matrices, with the
Numba kernels in :mod:`._kernels`. Only the effects a scene asks for are simulated
(:class:`~.layers.Effects`).

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["colour", "layers", "scenes", "scenes_depth", "scenes_temperature", "scenes_volume",
                "scenes_volume_temperature",
                "scenes_time", "tracer"],
    submod_attrs={
        "scenes": ["PAPER_DEPTHS_MM", "SHAPE_AT_DEPTH", "FLAME_HEIGHT_MEAN_MM", "FLAME_HEIGHT_SD_MM",
                 "REGIMES", "PAPER_RELATIVE_SD", "shapes_scene",
                 "flame_luminosity", "flame_centreline", "flame_scene", "FLAME_EFFECTS", "overlap_scene",
                 "point_scene", "white_scene", "SCENES"],
        "layers": ["Effects", "Layer", "Scene", "MAX_BIT_DEPTH", "light_outside_field"],
        "colour": ["render_colour"],
        "scenes_temperature": ["FLAME_PEAK_K", "FLAME_BASE_K", "BEHIND_PEAK_K", "flame_temperature", "ColourFlameScene",
                               "colour_flame_scene", "colour_behind_scene", "colour_depth_scene", "blackbody_channels",
                               "furnace_scene",
                               "FLICKER_K", "colour_flicker_frame"],
        "scenes_depth": ["DEPTH_RANGE_MM", "HEIGHT_RANGE_MM", "MIN_HALF_WIDTH_MM", "random_depth_scene",
                         "PAPER_SLOPE_RANGE", "camera_depth_ranges", "camera_depth_scene",
                         "behind_scene"],
        "scenes_volume": ["sheath_density", "volume_flame_scene", "axisymmetric_flame_scene",
                          "nonaxisymmetric_flame_scene"],
        "scenes_volume_temperature": ["TABLE_STEP_K", "axisymmetric_temperature_field", "axisymmetric_density",
                                      "colour_axisymmetric_scene", "axisymmetric_node_truth", "axisymmetric_voxel_truth"],
        "scenes_time": ["FlickerFlame", "FlameSequence", "SEQUENCE_KINDS", "flicker_sequence"],
        "tracer": ["NO_TABLE", "content_box", "backward_chain", "trace_coefficients", "render",
                 "render_points", "render_views", "render_reference", "apply_sensor"],
    },
)
