"""lf_flame: deep-learning light-field refocusing of burner flames, reproduced.

Modules: :mod:`~lf_flame.optics` (ray transfer matrices), :mod:`~lf_flame.camera`
(the plenoptic camera), :mod:`~lf_flame.scenes` (layered scenes),
:mod:`~lf_flame.simulate` (ray tracer), :mod:`~lf_flame.refocus` (shift-and-sum,
slope search), :mod:`~lf_flame.dataset` (HDF5 datasets), :mod:`~lf_flame.model`
(the Keras model), :mod:`~lf_flame.features` (backbone feature cache),
:mod:`~lf_flame.baselines` (mean image, linear decoders), :mod:`~lf_flame.closed_form`
(the network's closed-form start), :mod:`~lf_flame.train` (the training run),
:mod:`~lf_flame.model_files` (trained models loaded), :mod:`~lf_flame.evaluate`,
:mod:`~lf_flame.diagnostics` (flame measurements), :mod:`~lf_flame.calibrate` and
:mod:`~lf_flame.decode` (real cameras), :mod:`~lf_flame.cli` (the `lf-flame` command line).
"""
__version__ = "0.1.0"
