"""The paper's learning pipeline and its yardsticks.

:mod:`.dataset` renders HDF5 datasets with four refocused ground-truth planes per sample;
:mod:`.model` builds the paper's frozen ResNet-50 + decoder; :mod:`.features` caches the
backbone's features; :mod:`.baselines` the honest yardsticks (mean image, closed-form
linear decoders); :mod:`.closed_form` the network's closed-form start; :mod:`.training`
the training run; :mod:`.model_files` loads trained models; :mod:`.reconstructor` learns each
plane's emission on a physics start (the learned reconstructor); :mod:`.evaluation` scores
every route on the test split and writes Tables I and II.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["baselines", "closed_form", "dataset", "evaluation", "features", "model", "model_files", "reconstructor",
                "training"],
    submod_attrs={
        "baselines": ["RELATIVE_ALPHAS", "pool_features", "RidgePath", "ridge_path", "MeanImage",
                 "LinearDecoder", "choose_alpha_per_plane", "BASELINE_FILES", "load_baselines",
                 "fit_baselines"],
        "closed_form": ["set_population_statistics", "refine_dense", "pair_convolutions", "closed_form_start",
                 "gauss_newton_targets", "ridge_dense", "PROBE_LAYERS", "freeze_for_probe"],
        "dataset": ["RAW_SCALE", "SCENE_IDS", "GT_MASK", "sample_rng", "make_sample", "split_indices",
                 "IDENTITY_ATTRS", "content_digest", "shard_path", "generate", "check_dataset",
                 "LightFieldDataset", "calibrate_slopes"],
        "evaluation": ["PAPER_TABLES", "PAPER_SLOPES", "TABLE_NAMES", "ROUTES", "score", "route_predictions",
                 "HELDOUT2", "evaluate", "summarise", "below_the_mean_image", "table_markdown", "figure",
                 "learning_curves", "write_slopes", "plot_slope_curves", "read_gnu_time",
                 "provenance_section", "write_tables"],
        "features": ["feature_cache_path", "compute_features", "FeatureBatches", "predict_features",
                 "layer_outputs", "load_features"],
        "model": ["CAFFE_MEAN", "NOTOP_FILE", "resolve_weights", "build_feature_extractor",
                 "DROPOUT_PLACES", "build_decoder", "build_model", "compose"],
        "model_files": ["load_decoder", "load_full_model", "save_random_backbone"],
        "reconstructor": ["ReconstructorConfig", "LearnedReconstructor", "training_samples", "plane_inputs",
                          "build_network", "sensor_noise", "reconstruction"],
        "training": ["validation_scores", "train"],
    },
)
